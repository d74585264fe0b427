"""Judging a sweep's tables against the predictions (`docs/design.md` §6).

The suite and its report (suite), the checks (checks, promise, nrun, blocking), the tables they
read (data), the null model (null) and the outcome table (outcome); the sweep's HTML report and
the figures of the CLI (report), and the paper's claims reproduced (paper).
"""
