"""Statistical validation of a sweep (`docs/design.md` §6).

The suite and its report (suite),
the checks (checks, promise, nrun), the tables they read (data) and the null model (null).
"""
