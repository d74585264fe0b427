"""Reproduce the paper's claims: each one computed, drawn and judged from its own numbers.

A claim is a :class:`Claim`: the paper's statement, a verdict from a fixed vocabulary
(``holds``, ``holds only when <condition>``, ``does not hold``), the numbers the verdict was
computed from, a figure and a short explanation. The claims live in
:mod:`validation.paper.geometry` (two-marker geometry: claims 1, 2, 5, 6) and :mod:`validation.paper.pef`
(PEF, measurement cost, Monte-Carlo: claims 3, 4, 7); :func:`reproduce` runs them all and
:mod:`validation.paper.html` writes the page.

Every verdict is a function of the claim's numbers (the claim functions take their error
model as an argument, so a test can feed a wrong model and watch the verdict change).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from scenarios.errors import output_errors
from scenarios.jsonable import json_number

#: The paper's laser: 1 mm of error at 15 m (ch. 3), the relative range error Re [m/m].
PAPER_RE = 1e-3 / 15.0
#: Seed of the generators the claims draw random layouts from.
PAPER_SEED = 20240607

HOLDS = "holds"
DOES_NOT_HOLD = "does not hold"
ONLY_WHEN = "holds only when "


def only_when(condition: str) -> str:
    """Return the verdict ``holds only when <condition>``."""
    return ONLY_WHEN + condition


def is_verdict(text: str) -> bool:
    """Tell whether ``text`` is a verdict of the allowed vocabulary."""
    return text in (HOLDS, DOES_NOT_HOLD) or (text.startswith(ONLY_WHEN) and len(text) > len(ONLY_WHEN))


@dataclass
class Claim:
    """One reproduced claim of the paper.

    Attributes
    ----------
    id : int
        Claim number (1..7).
    title : str
        Short name.
    statement : str
        What the paper says (quoted or closely paraphrased, with its section).
    verdict : str
        ``holds``, ``holds only when <condition>`` or ``does not hold``.
    numbers : dict
        JSON-ready numbers the verdict was computed from (units in the key names).
    figure : pathlib.Path
        The PNG of the claim.
    explanation : str
        How the claim was tested and what the numbers say.
    seconds : float
        Wall time the claim took [s].
    """

    id: int
    title: str
    statement: str
    verdict: str
    numbers: dict[str, Any]
    figure: Path
    explanation: str
    seconds: float = field(default=0.0)

    def to_dict(self) -> dict[str, Any]:
        """Return the claim as JSON-ready data (``--json``)."""
        return {"id": self.id, "title": self.title, "verdict": self.verdict, "numbers": self.numbers,
                "figure": str(self.figure), "seconds": round(self.seconds, 2)}


def sig(x: Any, digits: int = 4) -> Any:
    """Round floats (also inside lists and dicts) to ``digits`` significant digits for the report.

    Non-finite floats become None so that the numbers stay valid JSON.
    """
    if isinstance(x, dict):
        return {k: sig(v, digits) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [sig(v, digits) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = json_number(float(x))
        if v is None:
            return None
        return 0.0 if v == 0.0 else float(f"{v:.{digits}g}")
    return x


def first_crossing(x: np.ndarray, y: np.ndarray, level: float) -> float | None:
    """Return the first ``x`` where ``y`` reaches ``level``, interpolated in log-log; None if never.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Increasing positive abscissae.
    y : ndarray, shape (n,)
        Positive values.
    level : float
        Level > 0.
    """
    above = np.flatnonzero(np.asarray(y) >= level)
    if above.size == 0:
        return None
    i = int(above[0])
    if i == 0:
        return float(x[0])
    lx, ly = np.log([x[i - 1], x[i]]), np.log([y[i - 1], y[i]])
    if ly[1] == ly[0]:
        return float(x[i])
    return float(np.exp(lx[0] + (math.log(level) - ly[0]) * (lx[1] - lx[0]) / (ly[1] - ly[0])))


def save_figure(fig: Any, path: Path) -> Path:
    """Write a matplotlib ``Figure`` to ``path`` as PNG and return the path."""
    from validation.report.figures import png_bytes

    with output_errors(path, "write the figure"):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(png_bytes(fig, dpi=100))
    return path


@dataclass(frozen=True)
class Options:
    """How much work :func:`reproduce` does.

    Attributes
    ----------
    quick : bool
        Fewer samples, coarser grids and fewer Monte-Carlo runs (for tests).
    runs : int or None
        Monte-Carlo runs of claim 7; default 10 (3 with ``quick``).
    workers : int or None
        Monte-Carlo worker processes; default the CPU count.
    """

    quick: bool = False
    runs: int | None = None
    workers: int | None = None
