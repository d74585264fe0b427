"""Shared test scenarios (the tiny worlds several test modules build) and one small real sweep."""

from __future__ import annotations

import contextlib
import io
import json
import os

# The fast tier runs one xdist worker per core; OpenBLAS's own threads (one per core in each
# worker) then oversubscribe the cores and spin: a 400k x 38 sample covariance took 12 s instead of
# 0.5 (tests/estimators/test_motion_quantised.py). One BLAS thread per worker. Set before any test
# module imports numpy, which reads it once.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest


def flat_text(size: float = 30.0, extra: str = "") -> str:
    """TOML of an empty square floor of ``size`` metres with two markers on its south wall.

    ``extra`` is appended (more tables or keys, e.g. a ``[robot]`` section).
    """
    return (f'name = "flat"\n[workspace]\nsize = [{size}, {size}]\n'
            f'[[markers]]\nid = "a"\nposition = [0.0, 0.0]\n[[markers]]\nid = "b"\nposition = [{size}, 0.0]\n'
            f'[sensor]\n[planning]\neps_max = 0.05\n{extra}')


@pytest.fixture(scope="session")
def small_validated_sweep(tmp_path_factory):
    """``pefsim validate paper-two-markers --runs 4 --out DIR --json``, run once per session.

    Real episodes, few: the wiring from a sweep's tables to the verdicts (``--from`` reads them
    back). The checks' power and their negative controls are tested on synthetic and transformed
    tables (``tests/validation``); the long real sweeps are in the e2e tier.

    Returns
    -------
    (pathlib.Path, int, dict)
        The sweep directory, the exit code and the JSON report.
    """
    import cli

    out = tmp_path_factory.mktemp("small-sweep") / "mc"
    buf = io.StringIO()  # a session-scoped fixture cannot use capsys
    with contextlib.redirect_stdout(buf):
        code = cli.main(["validate", "paper-two-markers", "--runs", "4", "--workers", "1", "--out", str(out),
                         "--json"])
    return out, code, json.loads(buf.getvalue())
