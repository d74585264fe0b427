"""A scenario without [[robots]] gives the tables it gave before fleets existed, bit for bit.

The digests were computed with the code of commit 3bb1324 (main before the fleet work), by the
same function, on a 3 s episode of task 0 with run 0's seed. A change that moves any number of
a single-robot episode (the laser's ray ends, the posts, the streams) changes them.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

import scenarios
from sim.episode.drive import run_episode
from sim.montecarlo.rows import fix_columns, run_row, step_columns

BEFORE_FLEETS = {
    "warehouse": "fda14489b1cf0859448fdf23b35c2d3e36a2f7fc2ce5da487520ed566b4285f0",
    "paper-two-markers": "88ea7e6cf38c9fed5de1c2bf486119f030c481529fa03849e07b673f474a3488",
}


def digest(name: str, seconds: float) -> str:
    """SHA-256 of a short episode's runs row, step columns and fix columns."""
    sc = scenarios.load(name)
    r = run_episode(sc, 0, seed=np.random.SeedSequence(sc.seed, spawn_key=(0,)), time_limit=seconds)
    h = hashlib.sha256()
    h.update(json.dumps(run_row(0, "s", 0, r.summary, None), sort_keys=True, default=repr).encode())
    for cols in (step_columns(0, r.steps), fix_columns(0, r.fixes)):
        for k in sorted(cols):
            h.update(k.encode())
            h.update(np.ascontiguousarray(cols[k]).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("name", sorted(BEFORE_FLEETS))
def test_single_robot_tables_are_those_before_fleets(name):
    assert digest(name, 3.0) == BEFORE_FLEETS[name]
