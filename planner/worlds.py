"""Random honest worlds that plan: draw (:mod:`scenarios.worlds`), choose eps_max, redraw until every task plans.

World ``index`` of root ``seed`` draws from its own generator,
``numpy.random.default_rng(SeedSequence(seed, spawn_key=(index,)))`` (the children
``SeedSequence(seed).spawn(n)`` would give), so it does not depend on how many worlds are drawn,
and the same ``(seed, index)`` gives the same text byte for byte.

eps_max is chosen from the world: each task is first planned with a loose eps_max
(``LOOSE_EPS``) to find the route's achievable error, the largest tau along the chosen route
or promise of its scheduled fixes; eps_max is the drawn factor (``scenarios.worlds.EPS_FACTOR_RANGE``) times the
largest over the tasks, rounded up to 0.1 mm. The world is then planned for real; when a task
has no admissible route (the drift between fixes needs more room than the factor left), the
factor grows by ``FACTOR_STEP`` up to ``FACTOR_TRIES`` times, and after that, or when a route has
no finite error at all, the world is redrawn from the same generator.

:class:`Drawing` draws worlds in worker processes (the executor protocol of
:mod:`sim.montecarlo.executors`): each world depends on ``(seed, index)`` alone, so the texts are
the same whatever the number of workers.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import tomli_w

import scenarios
from planner.plan import plan_route, plan_task
from scenarios.errors import PlanningError, ScenarioError, output_errors
from scenarios.limits import MAX_WORLDS
from scenarios.output_names import check_output_names
from scenarios.worlds import SMALLEST_MAX_SIZE, draw_world

LOOSE_EPS = 0.1
"""eps_max [m] of the first plan, which only asks for the chosen route's largest tau.

Loose against every error a drawn world achieves (millimetres to a few centimetres), but not
unbounded: the plan's line-of-sight margin grows with eps_max (:mod:`planner.pef.sight`), and at
0.1 m it stays narrow beside the drawn corridors (2.5 m and wider); at 50 m no marker was usable."""
FACTOR_STEP = 1.5
"""Growth of the eps_max factor when a task does not plan."""
FACTOR_TRIES = 3
"""eps_max factors tried before the world is redrawn."""
MAX_ATTEMPTS = 25
"""Draws tried for one world before giving up (PlanningError)."""


@dataclass(frozen=True)
class PlannedWorld:
    """A drawn world every task of which plans.

    Attributes
    ----------
    name : str
        The scenario's name (``random-<seed>-<index>``).
    text : str
        The scenario TOML, with a header comment saying its seed and what was drawn.
    scenario : scenarios.Scenario
        ``text`` loaded.
    attempts : int
        Draws it took (1 = the first draw planned).
    summary : tuple of str
        What was drawn, as in the header.
    path : pathlib.Path or None
        Where the text was written (set by ``pefsim.worlds`` with ``out``).
    """

    name: str
    text: str
    scenario: scenarios.Scenario
    attempts: int
    summary: tuple[str, ...]
    path: Path | None = None

    def to_dict(self) -> dict:
        """Return the world's record as a JSON-ready dict (what ``pefsim worlds --json`` prints; not the text)."""
        return {"name": self.name, "path": None if self.path is None else str(self.path), "attempts": self.attempts,
                "summary": list(self.summary)}


def world_rng(seed: int, index: int) -> np.random.Generator:
    """World ``index``'s generator under root ``seed`` (independent of how many are drawn)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))


def _with_eps(data: dict, eps: float, source: str) -> scenarios.Scenario:
    data["planning"]["eps_max"] = eps
    return scenarios.from_dict(data, source=source)


def _achievable(data: dict, source: str) -> float:
    """Return the achievable error [m] of a drawn world's tasks.

    Over the tasks, the largest tau along the route chosen under a loose eps_max, or the largest promise of its
    scheduled fixes (a moving fix, measured marker after
    marker, promises more than the static tau: up to 4x it with k = 4), whichever is larger.
    """
    sc = _with_eps(data, LOOSE_EPS, source)
    worst = 0.0
    for task in sc.tasks:
        p = plan_route(sc, task.start, task.goal)
        promises = [f.predicted_tau for f in p.schedule.fixes]
        worst = max(worst, float(p.candidates[p.chosen].max_tau), *promises)
    return worst


def _plans(sc: scenarios.Scenario) -> bool:
    try:
        for i in range(len(sc.tasks)):
            plan_task(sc, i)
    except PlanningError:
        return False
    return True


def plannable_world(seed: int, index: int, *, max_size: float | None = None, bounded: bool = False) -> PlannedWorld:
    """Draw world ``index`` of root ``seed``, redrawing until every task plans.

    Parameters
    ----------
    seed : int
        Root seed (>= 0).
    index : int
        The world's number (>= 0).
    max_size, bounded
        The draw's knobs (:func:`scenarios.worlds.draw_world`); the file's header names them.

    Returns
    -------
    PlannedWorld

    Raises
    ------
    PlanningError
        ``MAX_ATTEMPTS`` draws in a row did not plan (a defect of the generator).
    """
    rng = world_rng(seed, index)
    name = f"random-{seed}-{index:03d}"
    source = f"{name}.toml"
    for attempt in range(1, MAX_ATTEMPTS + 1):
        drawn = draw_world(rng, name, max_size=max_size, bounded=bounded)
        try:
            tau = _achievable(drawn.data, source)
        except PlanningError:
            continue
        if not math.isfinite(tau) or tau <= 0.0:
            continue
        factor = drawn.eps_factor
        for _ in range(FACTOR_TRIES):
            eps = math.ceil(factor * tau * 1e4) / 1e4
            try:
                sc = _with_eps(drawn.data, eps, source)
            except ScenarioError:
                break
            if _plans(sc):
                summary = (*drawn.summary,
                           f"eps_max {eps * 1000:g} mm = {factor:.3g} x {tau * 1000:.3g} mm, the achievable "
                           "error (largest tau or fix promise at cruising speed) along the chosen routes")
                knobs = ((f" --max-size {max_size:g}" if max_size is not None else "")
                         + (" --bounded" if bounded else ""))
                header = [f"# pefsim worlds --seed {seed}{knobs}: world {index}, drawn from numpy "
                          f"SeedSequence({seed}, spawn_key=({index},)), draw {attempt} (the ones before "
                          "did not plan)"] + [f"#   {line}" for line in summary]
                text = "\n".join(header) + "\n" + tomli_w.dumps(drawn.data)
                return PlannedWorld(name=name, text=text, scenario=scenarios.loads(text, source=source),
                                    attempts=attempt, summary=summary)
            factor *= FACTOR_STEP
    raise PlanningError(f"world {index} of seed {seed}: no draw planned in {MAX_ATTEMPTS} attempts")


@dataclass(frozen=True)
class Drawing:
    """Draw worlds of one root seed in a worker process: ``execute(index)`` is one world.

    Its own worker factory and context (``Drawing(payload)`` returns itself): what a worker
    needs is the seed and the draw's knobs, held here. The record is picklable text, not a
    :class:`PlannedWorld` (whose scenario the parent loads again, :meth:`world`).
    """

    seed: int
    max_size: float | None = None
    bounded: bool = False

    def __call__(self, payload: object = None) -> Drawing:
        return self

    def execute(self, index: int) -> tuple[int, str, str, int, tuple[str, ...]]:
        """Return ``(index, name, text, attempts, summary)`` of world ``index``."""
        w = plannable_world(self.seed, index, max_size=self.max_size, bounded=self.bounded)
        return index, w.name, w.text, w.attempts, w.summary

    def close(self) -> None:
        """Nothing to release."""

    def died(self, index: int, reason: str):
        raise PlanningError(f"world {index} of seed {self.seed}: the process drawing it died ({reason})")

    @staticmethod
    def world(record: tuple[int, str, str, int, tuple[str, ...]]) -> PlannedWorld:
        """Return the :class:`PlannedWorld` of an :meth:`execute` record (its scenario loaded)."""
        _, name, text, attempts, summary = record
        return PlannedWorld(name=name, text=text, scenario=scenarios.loads(text, source=f"{name}.toml"),
                            attempts=attempts, summary=tuple(summary))


Pool = Callable[[Drawing, list[int], int], Iterator[tuple]]
"""Runs ``Drawing.execute`` of each index on ``n`` worker processes and yields the records as they
finish: ``pool(drawing, indices, n)`` (the caller's executor, e.g. the sweeps' local pool)."""


def iter_worlds(count: int, *, seed: int = 0, out: str | Path | None = None, first: int = 0,
                max_size: float | None = None, bounded: bool = False, workers: int = 1,
                pool: Pool | None = None) -> Iterator[PlannedWorld]:
    """Yield worlds ``first .. first + count - 1`` of ``seed`` in order, each written into ``out`` as it is drawn.

    The arguments are checked and ``out`` is made when this is called, before any world is
    drawn; memory does not grow with ``count``, and an interrupted run keeps the worlds written.
    The parameters are :func:`pefsim.worlds`'s; ``pool`` draws on worker processes when
    ``workers`` > 1 (without one, every world is drawn in this process).

    Raises
    ------
    ScenarioError
        A count, seed, first index, floor size or worker count out of range.
    OutputError
        ``out`` cannot be made.
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ScenarioError(f"count: expected a whole number of worlds >= 1, got {count!r}")
    if count > MAX_WORLDS:
        raise ScenarioError(f"count: expected at most {MAX_WORLDS} worlds (each is drawn and planned, seconds "
                            f"a world), got {count}")
    for key, value in (("seed", seed), ("first", first)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ScenarioError(f"{key}: expected a whole number >= 0, got {value!r}")
    if max_size is not None and (isinstance(max_size, bool) or not isinstance(max_size, (int, float))
                                 or not max_size >= SMALLEST_MAX_SIZE or not math.isfinite(max_size)):
        raise ScenarioError(f"max_size: expected a floor side of at least {SMALLEST_MAX_SIZE:g} m, got {max_size!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ScenarioError(f"workers: expected a whole number >= 1, got {workers!r}")
    knobs = {"max_size": None if max_size is None else float(max_size), "bounded": bool(bounded)}
    drawn = _draw_worlds(Drawing(seed, **knobs), range(first, first + count), workers, pool)
    if out is None:
        return drawn
    check_output_names({"out": out})
    folder = Path(out)
    with output_errors(folder, "create the output directory"):  # before the drawing, which takes seconds a world
        folder.mkdir(parents=True, exist_ok=True)
    return _write_worlds(drawn, folder)


def _write_worlds(drawn: Iterator[PlannedWorld], folder: Path) -> Iterator[PlannedWorld]:
    """Write each world of ``drawn`` into ``folder`` as it comes, and yield it with its ``path``."""
    for w in drawn:
        path = folder / f"{w.name}.toml"
        with output_errors(path, "write the world"):
            path.write_text(w.text, encoding="utf-8")
        yield replace(w, path=path)


def _draw_worlds(drawing: Drawing, indices: range, workers: int, pool: Pool | None) -> Iterator[PlannedWorld]:
    """Yield the worlds of ``indices`` in order, drawn here (1 worker) or by ``pool``.

    The pool's records arrive as they finish; those ahead of the next index wait (about one per
    worker), so memory does not grow with the count.
    """
    if workers == 1 or len(indices) == 1 or pool is None:
        for i in indices:
            yield plannable_world(drawing.seed, i, max_size=drawing.max_size, bounded=drawing.bounded)
        return
    ahead: dict[int, tuple] = {}
    following = indices.start
    for record in pool(drawing, list(indices), min(workers, len(indices))):
        ahead[record[0]] = record
        while following in ahead:
            yield drawing.world(ahead.pop(following))
            following += 1
