"""The N-run checks wired into ``validate``: a sweep on disk with per-step NEES and per-fix NIS.

Steps and fixes come from the linear Kalman filter of ``tests/estimators/synthetic_kf.py``
(60 runs, 3000 steps, a fix of two updates every 20 steps), written in the real on-disk
format; the fixes' geometry is the paper's two markers (the other checks are not the
subject here). A consistent filter passes; a filter whose covariance is 20 % too small fails
the N-run NEES test and the pooled NEES (at 60 runs the pooled one uses the between-run spread).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import scenarios
from sim.montecarlo import results
from sim.montecarlo.results import RunRecord, SweepLayout
from sim.montecarlo.rows import STEP_SCHEMA, fix_columns, run_row
from tests.estimators import synthetic_kf as kf
from tests.validation.synthetic_fixes import FIXES_PER_RUN, fix_log
from validation import suite as validation
from validation.suite import CheckStatus

RUNS = 60


def _write(root, c: float, seed: int = 1):
    """Write and load a sweep whose filter claims c times the true covariance (NEES, NIS divided by c)."""
    sc = scenarios.load("paper-two-markers")
    rng = np.random.default_rng(seed)
    sw = kf.simulate(RUNS, rng, fix_every=3000 // FIXES_PER_RUN)
    layout = SweepLayout(root)
    layout.make_dirs()
    results.write_atomic(layout.scenario_toml, sc.text.encode())
    for run in range(RUNS):
        nees = sw.nees[run][np.isfinite(sw.nees[run])] / c
        k = nees.size
        steps = {name: np.zeros(k) for name in STEP_SCHEMA.names}
        steps.update(run=np.full(k, run), step=np.arange(k), t=np.arange(k) * kf.DT, nees=nees)
        log = fix_log(sc, rng, 1.0)
        log.nis[:] = np.nan_to_num(sw.nis[run], nan=2.0) / c
        row = run_row(run, f"s{run}", 0, {"reached": True, "violations": 0, "fixes": FIXES_PER_RUN,
                                                  "mean_nees": float(nees.mean())}, 0.1)
        results.write_record(layout, RunRecord(run, row, steps, fix_columns(run, log)))
    return validation.load_sweep(root)


@pytest.fixture(scope="module")
def consistent(tmp_path_factory):
    return validation.validate(_write(tmp_path_factory.mktemp("c") / "mc", 1.0))


def test_loading_reads_only_the_step_columns_the_checks_need(tmp_path):
    data = _write(tmp_path / "mc", 1.0)
    assert data.steps is not None and len(data.steps) > RUNS * 2000
    assert set(vars(data.steps)) == {"run", "step", "nees"}
    assert data.fixes.fix.max() == FIXES_PER_RUN - 1


def test_consistent_filter_passes_and_the_family_counts_six(consistent):
    s = {c.name: c.status for c in consistent.checks}
    assert s["nees"] is s["nis"] is s["nees_nrun"] is s["nis_nrun"] is CheckStatus.PASS
    assert consistent.statistical == 6 and consistent.alpha_per_check == pytest.approx(0.01 / 6)
    v = consistent.check("nees_nrun").values
    assert v["correlation_at_spacing"] <= 0.2 and v["spacing"] > 10  # the time correlation is real
    assert consistent.check("nees").values["spread_used"]
    json.dumps(consistent.to_dict(), allow_nan=False)


def test_overconfident_filter_fails_the_nrun_nees(tmp_path):
    report = validation.validate(_write(tmp_path / "mc", 0.8, seed=2))
    nrun = report.check("nees_nrun")
    assert nrun.status is CheckStatus.FAIL and "overconfident" in nrun.detail
    assert report.check("nees").status is CheckStatus.FAIL
    assert report.check("nis_nrun").status is CheckStatus.FAIL  # 20 % shifts each fix by ~1.5 band sigma
