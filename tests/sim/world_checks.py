"""What an episode of a random world must show whatever the noise drew: the checks the random-world tests share."""

from __future__ import annotations

import numpy as np

from planner.schedule.promise import POLYGON_TOLERANCE


def fix_table_complete(r) -> bool:
    """Every scheduled fix is taken (a row), merged into a later one (the laser was busy), failed or unreached."""
    s = r.summary
    return s["fixes"] + s["merged_fixes"] + s["skipped_fixes"] + s["unreached_fixes"] == s["scheduled_fixes"]


def over_promise(r) -> np.ndarray:
    """Return the fixes whose realised fault area exceeds the promise's allowance or eps_max.

    Improvised ones are left out.
    """
    fx = r.fixes
    beyond = fx.beyond_redundancy if fx.beyond_redundancy is not None else np.zeros(len(fx.t), bool)
    d = fx.fault_diameter
    real = np.isfinite(d) & ~beyond
    over = real & ((d > (1.0 + POLYGON_TOLERANCE) * fx.predicted_tau) | (d >= r.eps_max))
    return np.flatnonzero(over)
