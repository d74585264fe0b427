"""Fault areas.

The exact region of a fix's measurements (exact, its pieces, the two-range
closed form in annuli), its linearisation (strips, parallelogram, GDOP), and the moving fix
(ranges carried to the fix time by odometry, carried).
"""
