"""JSON out: numbers that JSON cannot hold (inf, NaN) become null, numpy values plain Python."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def json_number(v: Any) -> Any:
    """Return ``v`` as JSON holds it: numpy scalars as Python, inf and NaN as None, lists element-wise.

    Parameters
    ----------
    v : any
        A number, a numpy scalar, a list/tuple of them, or anything else (returned as is).
    """
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, (list, tuple)):
        return [json_number(x) for x in v]
    return v
