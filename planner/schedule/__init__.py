"""The measurement schedule.

Where to fix and with which markers (schedule, search), time along a path (pathtime), the
drift bound between fixes (drift), and the promise of a moving fix (promise).
"""
