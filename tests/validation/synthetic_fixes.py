"""Synthetic fixes along the paper's route, for the validation checks' tests on tables."""

from __future__ import annotations

import numpy as np

import scenarios
from estimators.snapshot import snapshot_fix
from planner.pef.map import PEF
from sim.episode.types import FixLog

FIXES_PER_RUN = 60


def fix_log(scenario, rng, error_scale: float) -> FixLog:
    """Make fixes along the paper's route A -> B with range errors ``error_scale`` times the model's."""
    sensor = scenario.sensor
    mk = scenario.marker_positions()
    truth = np.linspace([1.0, 1.5], [4.0, 3.0], FIXES_PER_RUN) + rng.normal(0.0, 0.05, (FIXES_PER_RUN, 2))
    tau = PEF(scenario).tau_subset(truth, np.array([0, 1]))
    cols = {k: [] for k in ("ranges", "rho", "snapshot", "cov", "diam", "contained", "polys")}
    for p in truth:
        r = np.hypot(*(p - mk).T)
        rho = sensor.range_bound(r)
        if sensor.noise is scenarios.NoiseModel.UNIFORM:
            e = rng.uniform(-1.0, 1.0, 2) * rho
        else:
            e = rng.normal(0.0, 1.0, 2) * rho / 3.0
        z = r + error_scale * e
        fix = snapshot_fix(mk, z, rho, prior=p + 0.01, noise=sensor.noise)
        cols["ranges"].append(z)
        cols["rho"].append(rho)
        cols["snapshot"].append(fix.position)
        cols["cov"].append(fix.covariance)
        cols["diam"].append(fix.fault_area.diameter)
        cols["contained"].append(fix.fault_area.contains(p))
        cols["polys"].append(np.zeros((0, 2)))
    n = FIXES_PER_RUN
    return FixLog(t=np.arange(n) * 0.2, markers=np.tile([0, 1], (n, 1)), ranges=np.array(cols["ranges"]),
                  rho=np.array(cols["rho"]), true_position=truth, snapshot=np.array(cols["snapshot"]),
                  snapshot_cov=np.array(cols["cov"]), fault_diameter=np.array(cols["diam"]),
                  fault_polygons=cols["polys"], contained=np.array(cols["contained"]),
                  predicted_tau=tau, static_tau=tau,
                  nis=np.zeros(n), n_accepted=np.full(n, 2))
