"""A PEF map's arrays as a NumPy ``.npz`` file (``pefsim map --npz``)."""

from __future__ import annotations

import os

import numpy as np

from planner.pef.result import PefMap
from scenarios.errors import output_errors


def write_npz(path: str | os.PathLike[str], pef_map: PefMap) -> None:
    """Write ``tau`` (ny, nx) [m, inf = no fix], ``x`` (nx,), ``y`` (ny,) [m] and ``best`` (ny, nx, k).

    Parameters
    ----------
    path : str or path-like
        Output file, written at exactly this path (whatever its extension).
    pef_map : PefMap
        The map.

    Raises
    ------
    OutputError
        When the file cannot be written.
    """
    with output_errors(path, "write the map arrays"):
        with open(path, "wb") as fh:  # a file object: numpy must not append ".npz" to the name
            np.savez_compressed(fh, tau=pef_map.tau, x=pef_map.x, y=pef_map.y, best=pef_map.best)
