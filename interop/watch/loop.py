"""The watch loop: poll the scenario's files, rebuild the view on a change, log it, report one line.

A bad edit (anything :class:`scenarios.PefsimError` says about the files) is reported and the
last good view stays; the loop goes on and the next good edit updates the view again. The set
of files followed is the scenario file plus every file the last good load read
(``Scenario.files``: floor plan, map image, route graph).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from interop.watch.files import FileSet
from interop.watch.view import View, ViewBuilder
from scenarios import PefsimError
from scenarios.load import load, resolve

POLL_INTERVAL = 0.2
"""Seconds between two looks at the files' modification times and sizes."""
SETTLE = 0.05
"""Seconds a changed file must stay unchanged before it is read: a save is often a truncation and
a write (or several writes), and the half-written file in between is not what was saved."""


@dataclass(frozen=True)
class Update:
    """One update of the view, as reported.

    Attributes
    ----------
    seconds : float
        Wall time from noticing the change to the view logged [s] (with the plans shown after
        the map, to the map logged).
    changed : tuple of Path
        The files that changed (the scenario file alone for the first view).
    view : View
        What is shown now.
    planned_seconds : float, optional
        Wall time from noticing the change to the plans logged [s], when they followed the map.
    """

    seconds: float
    changed: tuple[Path, ...]
    view: View
    planned_seconds: float | None = None

    def line(self) -> str:
        """Return the line printed: ``"updated in 0.23 s: hall.toml: 14 markers, 3 tasks planned"``.

        With the plans after the map: ``"updated in 0.23 s, planned in 0.91 s: hall.toml: ..."``.
        """
        names = ", ".join(p.name for p in self.changed)
        planned = "" if self.planned_seconds is None else f", planned in {self.planned_seconds:.2f} s"
        return f"updated in {self.seconds:.2f} s{planned}: {names}: {self.view.summary()}"


def watch_files(scenario: str | Path, show: Callable[[int, View], None], *,
                show_plans: Callable[[int, View], None] | None = None,
                on_update: Callable[[Update], None] | None = None,
                on_error: Callable[[PefsimError], None] | None = None,
                interval: float = POLL_INTERVAL, max_updates: int | None = None,
                stop: threading.Event | None = None) -> int:
    """Build and show the view of ``scenario``, then again whenever one of its files is saved.

    Parameters
    ----------
    scenario : str or path
        Scenario file (a built-in name is followed as its file in the library).
    show : callable (step, View)
        Logs a view (:func:`interop.recording.live.log_view`); step counts the updates from 0.
    show_plans : callable (step, View), optional
        Given: ``show`` gets the map part of each update (:meth:`ViewBuilder.build_map`: map,
        route segments; ``planned`` False) as soon as it is computed, and this the same view
        with its plans (:func:`interop.recording.live.log_plans`) when they follow. None: ``show``
        gets the whole view once.
    on_update : callable (Update), optional
        Called after each update is shown.
    on_error : callable (PefsimError), optional
        Called when a version of the files is refused (the last good view stays).
    interval : float
        Polling period [s].
    max_updates : int, optional
        Return after this many updates (the first view included); default: run until ``stop``
        is set or the process is interrupted.
    stop : threading.Event, optional
        Return once it is set (checked every ``interval``).

    Returns
    -------
    int
        Number of updates shown.
    """
    path = resolve(scenario).resolve()
    files = FileSet([path])
    builder = ViewBuilder()
    updates = 0
    changed: list[Path] = [path]
    read: dict[Path, bytes | None] | None = None  # the content of each file at the last attempt
    while True:
        if changed:
            while more := files.changed():  # until the writes have settled
                changed = list(dict.fromkeys([*changed, *more]))
                time.sleep(SETTLE)
            if read is not None:  # a change back to what was read is none
                changed = [p for p in changed if files.digest(p) != read.get(p)]
        if changed:
            t0 = time.perf_counter()
            try:
                sc = load(scenario)  # errors name the file as given, as the CLI does
                view = builder.build(sc) if show_plans is None else builder.build_map(sc)
                show(updates, view)
            except PefsimError as exc:
                time.sleep(SETTLE)
                if more := files.changed():  # read while still being written (truncated, then filled): again
                    changed = list(dict.fromkeys([*changed, *more]))
                    continue
                read = {p: files.digest(p) for p in files.stamps}
                if on_error is not None:
                    on_error(exc)
            else:
                seconds, planned = time.perf_counter() - t0, None
                if show_plans is not None:  # the map is on screen; the plans follow
                    try:
                        view = builder.plan(view)
                        show_plans(updates, view)
                        planned = time.perf_counter() - t0
                    except PefsimError as exc:  # the map stays shown, without plans
                        if on_error is not None:
                            on_error(exc)
                updates += 1
                files.follow(dict.fromkeys([path, *view.scenario.files]))
                read = {p: files.digest(p) for p in files.stamps}
                if on_update is not None:
                    on_update(Update(seconds, tuple(changed), view, planned))
                if max_updates is not None and updates >= max_updates:
                    return updates
        if stop is not None and stop.wait(interval):
            return updates
        if stop is None:
            time.sleep(interval)
        changed = files.changed()
