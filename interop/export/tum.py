"""TUM trajectory export (``t x y z qx qy qz qw``), readable by evo and other trajectory tools."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import numpy as np

from scenarios.errors import output_errors

TUM_FILES = ("groundtruth.txt", "estimate.txt")
"""The files written into the TUM folder: the true trajectory, then the estimated one."""


def tum_rows(t: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """TUM rows, shape (T, 8), for times ``t`` (T,) [s] and planar poses ``pose`` (T, 3).

    The robot is planar: z = 0 and the orientation is a rotation about z by theta.
    """
    half = 0.5 * pose[:, 2]
    zeros = np.zeros_like(t)
    return np.column_stack([t, pose[:, 0], pose[:, 1], zeros, zeros, zeros, np.sin(half), np.cos(half)])


def make_folder(directory: str | Path) -> Path:
    """Create ``directory`` (and its parents) for the TUM files and check it can be written, before the episode.

    Raises :class:`OutputError` naming the directory when it cannot be created or written.
    """
    d = Path(directory)
    with output_errors(d, "write TUM trajectories"):
        d.mkdir(parents=True, exist_ok=True)
        if not os.access(d, os.W_OK | os.X_OK):
            raise PermissionError(errno.EACCES, "Permission denied")
    return d


def write_tum(directory: str | Path, t: np.ndarray, true_pose: np.ndarray, est_pose: np.ndarray) -> tuple[Path, Path]:
    """Write ``groundtruth.txt`` and ``estimate.txt`` (the same timestamps in both) into ``directory``.

    Returns the two paths. Raises :class:`OutputError` if the directory cannot be written.
    """
    d = Path(directory)
    with output_errors(d, "write TUM trajectories"):
        d.mkdir(parents=True, exist_ok=True)
        paths = tuple(d / name for name in TUM_FILES)
        header = "# timestamp tx ty tz qx qy qz qw"
        for path, pose in zip(paths, (true_pose, est_pose), strict=True):
            # 9 decimals: nanoseconds and nanometres, so the RMSE recomputed from the files matches
            np.savetxt(path, tum_rows(t, pose), fmt="%.9f", header=header, comments="")
    return paths


def read_tum(path: str | Path) -> np.ndarray:
    """Read a TUM file into an array of shape (T, 8)."""
    return np.loadtxt(path, comments="#", ndmin=2)
