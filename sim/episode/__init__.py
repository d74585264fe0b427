"""One run in PyBullet.

One robot driving its plans (driver), scheduled alone (drive) or as a fleet under zone control
(fleet), the choice between them for a scenario (run), the compiled control step (control_tick),
the path follower (follower), the fixes (fixes), what a run did (outcome), its printout
(printout) and the result types (types).
"""
