"""One episode in PyBullet.

The drive loop (drive), its compiled control step (control_tick),
the path follower (follower), the fixes (fixes) and the result types (types).
"""
