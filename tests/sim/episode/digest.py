"""One hash of an episode's arrays, to compare episodes run in different processes."""

from __future__ import annotations

import hashlib

import numpy as np


def digest(result) -> str:
    """Return the SHA-256 of the steps' times, poses and covariances and the fixes' ranges, positions and markers."""
    h = hashlib.sha256()
    for a in (result.steps.t, result.steps.true_pose, result.steps.est_pose, result.steps.est_cov,
              result.fixes.ranges, result.fixes.snapshot, result.fixes.markers):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()
