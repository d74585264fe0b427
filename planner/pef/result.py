"""What the PEF returns: values at points (:class:`PefResult`), grids (:class:`PefMap`), cell centres."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenarios.errors import PlanningError
from scenarios.jsonable import json_number
from scenarios.schema import PefModel

#: Largest grid :meth:`planner.pef.map.PEF.grid` builds (cells), to turn a typo in the resolution into an error.
MAX_CELLS = 25_000_000


@dataclass(frozen=True)
class PefResult:
    """PEF at points.

    Attributes
    ----------
    tau : ndarray, shape (N,)
        Predicted error [m]; inf where no k-subset is visible or the point is not free.
    best : ndarray of int, shape (N, k)
        Marker indices (into ``scenario.markers``) of the best subset, ascending; -1 where none.
    tau_plain : ndarray, shape (N,)
        The best-subset tau with every visible marker [m]; equal to ``tau`` when r = 0.
    fallback : ndarray of int, shape (N, k, k)
        ``fallback[n, j]``: the best subset without marker ``best[n, j]`` (-1 where none, and
        everywhere when r = 0).
    """

    tau: np.ndarray
    best: np.ndarray
    tau_plain: np.ndarray | None = None
    fallback: np.ndarray | None = None


@dataclass(frozen=True)
class PefMap:
    """PEF on the cell centres of a grid covering the workspace.

    Attributes
    ----------
    x : ndarray, shape (nx,)
        Cell-centre x coordinates [m].
    y : ndarray, shape (ny,)
        Cell-centre y coordinates [m].
    tau : ndarray, shape (ny, nx)
        Predicted error [m]; inf where fewer than k markers are visible or inside obstacles.
    best : ndarray of int, shape (ny, nx, k)
        Marker indices of the best subset; -1 where none.
    free : ndarray of bool, shape (ny, nx)
        Cell centre in free space (in the workspace, outside every obstacle).
    model : PefModel
        The error model.
    cell_size : (float, float)
        Cell width and height [m] (the workspace divided evenly, closest to the resolution).
    redundancy : int
        r: ``tau`` is tau_r, the worst over r visible markers blocked (:mod:`planner.pef.map`).
    tau_plain : ndarray, shape (ny, nx)
        The best-subset tau with every visible marker [m] (``tau`` itself when r = 0).
    eps_max : float
        The allowed error the map is read against [m] (the scenario's ``planning.eps_max``).
    resolution : float
        The cell size asked for [m] (NaN: a window of centres, :meth:`planner.pef.map.PEF.cells`).
    speed : float or None
        The driving speed of a motion-aware map [m/s]; None: the static PEF.
    """

    x: np.ndarray
    y: np.ndarray
    tau: np.ndarray
    best: np.ndarray
    free: np.ndarray
    model: PefModel
    cell_size: tuple[float, float]
    redundancy: int = 0
    tau_plain: np.ndarray | None = None
    eps_max: float = math.nan
    resolution: float = math.nan
    speed: float | None = None

    def navigable(self, eps_max: float) -> np.ndarray:
        """Cells of the navigation region ``tau < eps_max``, shape (ny, nx) bool."""
        return self.free & (self.tau < eps_max)

    def to_dict(self) -> dict:
        """Return the map's summary as a JSON-ready dict (what ``pefsim map --json`` prints).

        Returns
        -------
        dict
            ``model``, ``resolution`` [m], ``eps_max`` [m], ``fraction_navigable`` (of free cells,
            ``tau < eps_max``), ``tau_min``/``tau_median``/``tau_max`` [m] over finite free cells
            (null when there are none), ``cells`` (nx * ny), ``shape`` [ny, nx], ``free_cells``,
            ``speed`` [m/s] (null: the static PEF).
        """
        tau_free = self.tau[self.free]
        finite = tau_free[np.isfinite(tau_free)]
        n_free = int(self.free.sum())
        return {
            "model": self.model.value,
            "resolution": float(self.resolution),
            "eps_max": float(self.eps_max),
            "fraction_navigable": float(np.count_nonzero(tau_free < self.eps_max) / n_free) if n_free else 0.0,
            "tau_min": json_number(finite.min()) if finite.size else None,
            "tau_median": json_number(float(np.median(finite))) if finite.size else None,
            "tau_max": json_number(finite.max()) if finite.size else None,
            "cells": int(self.tau.size),
            "shape": [int(self.y.size), int(self.x.size)],
            "free_cells": n_free,
            "speed": self.speed,
        }


def grid_centres(size: tuple[float, float], resolution: float,
                 origin: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres of the grid that divides the workspace evenly into cells of about ``resolution``.

    Parameters
    ----------
    size : (float, float)
        Workspace width and height [m].
    resolution : float
        Wanted cell size [m] > 0.
    origin : (float, float)
        Lower-left corner of the workspace (``Workspace.origin``) [m].

    Returns
    -------
    x : ndarray, shape (nx,)
        ``x0 + (i + 1/2) * width / nx`` with ``nx = max(1, round(width / resolution))`` [m].
    y : ndarray, shape (ny,)
        Likewise for the height [m].
    """
    if not (resolution > 0.0 and math.isfinite(resolution)):
        raise PlanningError(f"resolution: expected a positive number of metres, got {resolution}")
    # float counts (1e-300 m gives inf, not a 300-digit int), before any array is allocated
    counts = [q if q > 1e15 else max(1.0, float(round(q))) for q in (extent / resolution for extent in size)]
    cells = counts[0] * counts[1]
    if cells > MAX_CELLS:  # before the axes are allocated (1e-7 m asked for 1.6 GB of them)
        raise PlanningError(f"resolution: {resolution} m gives {cells:.3g} cells (at most {MAX_CELLS})")
    out = []
    for extent, start, n in zip(size, origin, counts, strict=True):
        out.append(float(start) + (np.arange(int(n)) + 0.5) * (extent / n))
    return out[0], out[1]
