"""Random honest worlds in the fast tier: three small bounded worlds drawn, planned and driven once.

``pefsim.worlds(max_size=MAX_SIZE, bounded=True)`` draws floors no larger than 12 m with uniform
(bounded) noise and set-membership PEF models, so what is asserted cannot fail by chance: the
episode finishes, every scheduled fix is accounted for, every fix's true position lies in its
realised exact fault area, and every realised area is within its promise (the allowance
``tests/sim/test_random_worlds.py`` states). The e2e tier drives larger worlds
(``test_random_worlds.py``); the statistical checks live in ``benchmarks/generalization.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

import pefsim
from tests.sim.world_checks import fix_table_complete, over_promise

SEED = 1
COUNT = 3
MAX_SIZE = 12.0


@pytest.fixture(scope="module")
def small_worlds():
    worlds = pefsim.worlds(COUNT, seed=SEED, max_size=MAX_SIZE, bounded=True)
    return [(w, pefsim.run_episode(w.scenario, seed=0, task=0)) for w in worlds]


def test_small_bounded_worlds_are_what_was_asked(small_worlds):
    kinds = set()
    for w, _ in small_worlds:
        sc = w.scenario
        assert max(sc.workspace.size) <= MAX_SIZE, (w.name, sc.workspace.size)
        assert sc.sensor.noise.value == "uniform" and sc.planning.pef_model.value != "gdop", w.name
        assert w.text.startswith(f"# pefsim worlds --seed {SEED} --max-size 12 --bounded: world ")
        kinds.add(w.summary[0].split()[1])
    assert len(kinds) == COUNT  # three layouts, not one thrice


def test_small_worlds_keep_what_cannot_fail_by_chance(small_worlds):
    for w, r in small_worlds:
        s = r.summary
        assert s["reached"], (w.name, s)
        assert s["fixes"] > 0 and fix_table_complete(r) and s["unreached_fixes"] == 0, (w.name, s)
        missed = np.flatnonzero(~r.fixes.contained)
        assert missed.size == 0, f"{w.name}: fixes {missed[:5].tolist()} miss the true position"
        over = over_promise(r)
        ratio = r.fixes.fault_diameter[over] / r.fixes.predicted_tau[over]
        assert over.size == 0, f"{w.name}: fixes {over[:5].tolist()} over their promise, x{ratio[:5]}"


@pytest.mark.parametrize(("flag", "value", "key"), [("--max-size", "11", "max_size"), ("--max-size", "nan", "max_size"),
                                               ("--workers", "0", "workers"), ("--workers", "-2", "workers")])
def test_cli_bad_knob_is_one_line_and_writes_nothing(tmp_path, capsys, flag, value, key):
    from cli import main

    out = tmp_path / "w"
    assert main(["worlds", "--count", "2", flag, value, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0] and value in err[0]
    assert not out.exists()
