"""Run every claim of the paper: the list of claim functions and :func:`reproduce`.

Apart from :mod:`validation.paper.claims` (the claim type, the verdicts, the options) so that the
claim modules (:mod:`validation.paper.geometry`, :mod:`validation.paper.pef`) import the claim type and this
module imports them: no cycle.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from scenarios.errors import output_errors
from validation.paper import geometry as geo
from validation.paper import pef
from validation.paper.claims import PAPER_SEED, Claim, Options


def claim_functions() -> list[Callable[..., Claim]]:
    """Return the claim functions in order; each takes ``(out_dir, options, rng)`` and returns a Claim."""
    return [geo.reproduce_alpha, geo.reproduce_equal_ranges, pef.reproduce_more_markers,
            pef.reproduce_measurement_cost, geo.reproduce_parallelogram, geo.reproduce_gdop,
            pef.reproduce_planned_route]


def reproduce(out_dir: str | Path, options: Options | None = None,
              only: set[int] | None = None) -> list[Claim]:
    """Reproduce the claims, writing figures to ``out_dir/figures`` (and claim 7's sweep to ``out_dir/mc``).

    Parameters
    ----------
    out_dir : path
        Output directory (created).
    options : Options, optional
        Sample sizes; default the full run.
    only : set of int, optional
        Claim ids to run; default all.

    Returns
    -------
    list of Claim
        In claim order.
    """
    out = Path(out_dir)
    with output_errors(out, "create the output directory"):
        (out / "figures").mkdir(parents=True, exist_ok=True)
    options = options or Options()
    # One generator per claim, spawned from a fixed seed: a claim's numbers do not depend on
    # which other claims ran.
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(PAPER_SEED).spawn(7)]
    claims = []
    for i, fn in enumerate(claim_functions(), start=1):
        if only is not None and i not in only:
            continue
        start = time.perf_counter()
        claim = fn(out, options, rngs[i - 1])
        claim.seconds = time.perf_counter() - start
        claims.append(claim)
    return claims
