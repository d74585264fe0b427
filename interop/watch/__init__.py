"""``pefsim watch``: follow a scenario's files and keep a live rerun view of it up to date.

:mod:`interop.watch.files` notices saved files (polling), :mod:`interop.watch.view` computes what the
view shows (reusing the PEF map where the edit cannot have changed it) and
:mod:`interop.watch.loop` ties both to a stream of :mod:`interop.recording.live`.
"""
