"""A task index is checked once: planning, one run and a sweep refuse a bad one with the same line."""

from __future__ import annotations

import numpy as np
import pytest

import pefsim
from scenarios import ScenarioError, load
from scenarios.tasks import check_task


@pytest.fixture(scope="module")
def docks():
    return load("paper-docks")


@pytest.mark.parametrize("task", [-1, 1, True, 0.0, "0", None])
def test_a_task_that_is_no_index_of_the_tasks_is_refused(docks, task):
    n = len(docks.tasks)
    assert n == 1, "the range below is the built-in scenario's"
    with pytest.raises(ScenarioError, match=r"^task: expected 0 \.\. 0 \(1 tasks in .*paper-docks.*\), got ") as err:
        check_task(docks, task)
    assert "\n" not in str(err.value)


def test_an_index_is_returned_as_an_int(docks):
    assert check_task(docks, np.int64(0)) == 0 and type(check_task(docks, np.int64(0))) is int


def test_every_entry_point_gives_the_same_line(docks, tmp_path):
    """The facade's plan, run and sweep reach the one check (a copy would word it differently)."""
    seen = set()
    for call in (lambda: pefsim.plan(docks, 3), lambda: pefsim.run_episode(docks, task=3),
                 lambda: pefsim.sweep(docks, tmp_path / "sw", runs=2, workers=1, task=3)):
        with pytest.raises(ScenarioError) as err:
            call()
        seen.add(str(err.value))
    assert seen == {f"task: expected 0 .. 0 (1 tasks in {docks.source}), got 3"}
    assert not (tmp_path / "sw").exists()


def test_a_negative_control_an_index_in_range_passes(docks):
    """Negative control: the check refuses nothing that indexes the tasks."""
    assert check_task(docks, 0) == 0
