"""The position error function.

Its models and maps (map), line-of-sight visibility
(visibility), and the compiled kernels behind them (kernels, pairs, scalar, threads).
"""
