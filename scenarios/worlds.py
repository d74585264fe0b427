"""Random honest worlds: draw one scenario from a ``numpy.random.Generator``.

A world is *honest* when the declared sensor and robot are the simulated ones (no
``[sensor.actual]``, no ``[robot.actual]``): a validation FAIL on it is a defect of pefsim, never
of the world. :func:`draw_world` spans what users run (DESIGN §8):

- layouts: a **loop** of corridors with 90° corners around an island (a box, a chamfered
  polygon or a ring: a polygon with a hole), a **U-turn** around a divider with dead-end ends,
  a **comb** of dead-end aisles off a main corridor, an **L-shaped** hall (a polygon filling
  the other corner); round pillars (circle obstacles) beside the outer walls;
- reflectors on the corridor walls at a drawn spacing: posts, flat ones facing into the
  corridor (their normal is the wall's), or both; k = 2-4 markers per fix;
- every PEF model (``parallelogram`` only with k = 2), uniform and gaussian noise, bearings on
  or off, Re log-uniform in [1e-5, 2e-3], ρ0 log-uniform in [0.5, 5] mm;
- the robot: speed 0.3-1.5 m/s, 512-4096 encoder ticks, wheel slip (``robot.odometry_noise``)
  0-2 %; ``robot.turn_slip`` is the simulated robot's own, :data:`TURN_SLIP`, written out (0 would
  leave the filter overconfident in turns, which is a dishonest world);
- the workspace origin at 0 or up to 900 km away (``workspace.origin``);
- redundancy 0, or 1 with ``sensor.block_probability`` in [0.05, 0.25].

Two knobs narrow the draw (both off by default; off, the draw is the same as without them):
``max_size`` caps the floor's sides (:data:`SMALLEST_MAX_SIZE` and up: small floors, short tasks,
quick to plan and drive), and ``bounded`` makes every claim deterministic (uniform noise, and a
set-membership PEF model: ``strips`` where ``gdop`` was drawn). Each knob changes only the values
it names; the generator's stream is consumed as without it.

Docks sit where routes between them turn corners (and in dead ends). ``planning.eps_max`` is
left to the caller: choosing it needs the PEF along the route (a planner question), so the draw
returns the factor ``eps_factor`` the caller multiplies the achievable error by
(:mod:`planner.worlds`). The draw is pure: the same generator state gives the same world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from scenarios.body import body_reach
from scenarios.schema import RobotSpec

KINDS = ("loop", "u-turn", "comb", "l-hall")
"""Layouts :func:`draw_world` chooses from, with equal probability."""
MODELS_K2 = ("exact", "parallelogram", "strips", "gdop")
MODELS_K = ("exact", "strips", "gdop")
MAX_MARKERS = {2: 36, 3: 20, 4: 13}
"""Most reflectors per world for k markers per fix: the PEF scores every k-subset at every
point, C(M, k) of them (630, 1140 and 715 here), which keeps a plan well under a second."""
RE_RANGE = (1e-5, 2e-3)
"""sensor.relative_error, drawn log-uniform."""
RHO0_RANGE = (0.0005, 0.005)
"""sensor.absolute_error [m], drawn log-uniform."""
SPEED_RANGE = (0.3, 1.5)
"""robot.max_speed [m/s]."""
TICKS_RANGE = (512, 4096)
"""robot.encoder_ticks, log-uniform integers."""
SLIP_RANGE = (0.0, 0.02)
"""robot.odometry_noise (per-increment wheel slip, relative std)."""
FAR_ORIGIN = 900_000.0
"""Largest |coordinate| of a far workspace origin [m] (a UTM easting is < 900 km)."""
TURN_SLIP = 0.13
"""robot.turn_slip of the simulated robots (measured; scenarios/library/README.md): with 0 declared,
a world that drew NEES 5.87 (interval [1.57, 5.02], 20 runs) passes at 3.15 with 0.13, same seeds."""
BLOCK_RANGE = (0.05, 0.25)
"""sensor.block_probability of a redundancy-1 world."""
EPS_FACTOR_RANGE = (1.15, 1.8)
"""eps_max / the achievable error along the chosen route (its largest tau or fix promise at
cruising speed, :mod:`planner.worlds`): plannable, not trivially (a tight draw makes the schedule
slow down or fix more often)."""
WALL_MARGIN = 0.3
"""Reflectors keep this far from a wall's ends [m] (off the corners)."""
SMALLEST_MAX_SIZE = 12.0
"""Smallest ``max_size`` [m]: a loop's island keeps 2.6 m between corridors 3.2 m wide, a comb two
aisles 3 m wide."""
SMALL_SIDE = 0.75
"""Under ``max_size``, a side whose range starts above the cap is drawn from this fraction of the cap up."""


@dataclass(frozen=True)
class Wall:
    """A straight wall reflectors can be mounted on: from ``a`` to ``b`` [m], ``normal`` into the open."""

    a: tuple[float, float]
    b: tuple[float, float]
    normal: tuple[float, float]

    @property
    def length(self) -> float:
        return math.hypot(self.b[0] - self.a[0], self.b[1] - self.a[1])


@dataclass
class Layout:
    """The geometry of a drawn world in local coordinates (origin at the lower-left corner) [m]."""

    kind: str
    size: tuple[float, float]
    obstacles: list[dict[str, Any]]
    walls: list[Wall]
    nodes: dict[str, tuple[float, float]]
    segments: list[tuple[str, str]]
    docks: list[str]
    tasks: list[tuple[str, str]]
    corridor: float
    features: list[str] = field(default_factory=list)


@dataclass
class DrawnWorld:
    """A drawn world: the scenario as a TOML-ready dict, what was drawn, and the eps_max factor.

    Attributes
    ----------
    data : dict
        The scenario's tables (``scenarios.from_dict`` loads it); ``planning.eps_max`` is a
        placeholder until the caller sets it.
    summary : list of str
        What was drawn, one short phrase each (for the file's header comment).
    eps_factor : float
        eps_max = eps_factor x the largest tau along the chosen route.
    """

    data: dict[str, Any]
    summary: list[str]
    eps_factor: float


def _u(rng: np.random.Generator, lo: float, hi: float, nd: int = 2) -> float:
    return round(float(rng.uniform(lo, hi)), nd)


def _side(rng: np.random.Generator, lo: float, hi: float, cap: float | None) -> float:
    """Draw a floor side [m]: uniform in [lo, hi]; under ``cap``, in [min(lo, SMALL_SIDE t), t], t = min(hi, cap)."""
    if cap is None:
        return _u(rng, lo, hi)
    top = min(hi, cap)
    return _u(rng, min(lo, SMALL_SIDE * top), top)


def _log_u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _sig(x: float, digits: int = 3) -> float:
    """``x`` rounded to ``digits`` significant digits (short, exact-looking file values)."""
    return float(f"{x:.{digits}g}")


def _box(x0: float, y0: float, x1: float, y1: float) -> dict[str, Any]:
    return {"center": [round((x0 + x1) / 2, 4), round((y0 + y1) / 2, 4)],
            "size": [round(x1 - x0, 4), round(y1 - y0, 4)]}


def _rect(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def _chamfered(x0: float, y0: float, x1: float, y1: float, ch: float) -> list[list[float]]:
    return [[x0 + ch, y0], [x1 - ch, y0], [x1, y0 + ch], [x1, y1 - ch], [x1 - ch, y1], [x0 + ch, y1],
            [x0, y1 - ch], [x0, y0 + ch]]


def _fitting_wheel_base(robot: dict[str, Any]) -> float:
    """Return the drawn wheel base, narrowed in centimetres until the body lies within the radius.

    The loader refuses a radius that does not contain the simulated body
    (:func:`scenarios.body.body_reach`: the wheels' contact spheres reach ``wheel_base / 2 +
    wheel radius``); the other draws stay as they were.
    """
    spec = RobotSpec(wheel_radius=robot["wheel_radius"], wheel_base=robot["wheel_base"], radius=robot["radius"],
                     wheel_radius_error=robot["wheel_radius_error"])
    while body_reach(spec).distance > spec.radius:
        spec = replace(spec, wheel_base=round(spec.wheel_base - 0.01, 2))
    return spec.wheel_base


def _pillars(rng: np.random.Generator, walls: list[Wall], robot_radius: float,
             corridor: float) -> list[dict[str, Any]]:
    """0-2 round pillars standing 5 cm off outer walls, in the middle 40 % of the wall.

    A route segment runs parallel to each of ``walls`` at ``corridor / 2``; a pillar's far side
    keeps ``robot_radius`` + 10 cm from it (the loader refuses a segment closer than the radius).
    """
    out = []
    r_max = (corridor / 2 - 0.05 - robot_radius - 0.1) / 2
    if r_max < 0.1 or not walls:
        return out
    for _ in range(int(rng.integers(0, 3))):
        wall = walls[int(rng.integers(len(walls)))]
        r = _u(rng, 0.1, min(r_max, 0.3))
        t = float(rng.uniform(0.3, 0.7))
        p = np.array(wall.a) + t * (np.array(wall.b) - np.array(wall.a)) + (0.05 + r) * np.array(wall.normal)
        out.append({"center": [round(float(p[0]), 3), round(float(p[1]), 3)], "radius": r})
    return out


def _loop(rng: np.random.Generator, robot_radius: float, cap: float | None) -> Layout:
    w, h, c = _side(rng, 14, 26, cap), _side(rng, 9, 15, cap), _u(rng, 2.2, 3.2)
    variant = ("box", "polygon", "ring")[int(rng.integers(3))]
    x0, y0, x1, y1 = c, c, w - c, h - c
    ch = 0.0
    if variant == "box":
        island: dict[str, Any] = _box(x0, y0, x1, y1)
    elif variant == "polygon":
        ch = _u(rng, 0.3, 1.0)
        island = {"polygon": _chamfered(x0, y0, x1, y1, ch)}
    else:
        t = _u(rng, 0.2, 0.5)
        island = {"polygon": _rect(x0, y0, x1, y1), "holes": [_rect(x0 + t, y0 + t, x1 - t, y1 - t)]}
    walls = [Wall((0, 0), (w, 0), (0, 1)), Wall((0, h), (w, h), (0, -1)),
             Wall((0, 0), (0, h), (1, 0)), Wall((w, 0), (w, h), (-1, 0)),
             Wall((x0 + ch, y0), (x1 - ch, y0), (0, -1)), Wall((x0 + ch, y1), (x1 - ch, y1), (0, 1)),
             Wall((x0, y0 + ch), (x0, y1 - ch), (-1, 0)), Wall((x1, y0 + ch), (x1, y1 - ch), (1, 0))]
    hc = c / 2
    nodes = {"A": (round(_u(rng, 0.25, 0.45) * w, 2), hc), "B": (round(_u(rng, 0.55, 0.75) * w, 2), h - hc),
             "c00": (hc, hc), "c10": (w - hc, hc), "c11": (w - hc, h - hc), "c01": (hc, h - hc)}
    segments = [("A", "c00"), ("A", "c10"), ("c10", "c11"), ("c11", "B"), ("B", "c01"), ("c01", "c00")]
    obstacles = [island] + _pillars(rng, walls[:4], robot_radius, c)
    tasks = [("A", "B")] if rng.random() < 0.5 else [("A", "B"), ("B", "A")]
    return Layout("loop", (w, h), obstacles, walls, nodes, segments, ["A", "B"], tasks, c,
                  [f"{variant} island", "90° corners"])


def _u_turn(rng: np.random.Generator, robot_radius: float, cap: float | None) -> Layout:
    w, c, t = _side(rng, 16, 26, cap), _u(rng, 2.2, 3.2), _u(rng, 0.2, 0.8)
    h = round(2 * c + t, 4)
    tip = w - c
    if rng.random() < 0.5:
        divider: dict[str, Any] = _box(0.0, c, tip, c + t)
        variant = "box divider"
    else:  # a rounded end: half an octagon beyond the tip
        r = t / 2
        arc = [[round(tip - r + r * math.cos(a), 4), round(c + r + r * math.sin(a), 4)]
               for a in np.linspace(-math.pi / 2, math.pi / 2, 5)]
        divider = {"polygon": [[0.0, c]] + arc + [[0.0, round(c + t, 4)]]}
        variant = "round-ended polygon divider"
    walls = [Wall((0, 0), (w, 0), (0, 1)), Wall((0, h), (w, h), (0, -1)), Wall((w, 0), (w, h), (-1, 0)),
             Wall((0, 0), (0, c), (1, 0)), Wall((0, c + t), (0, h), (1, 0)),
             Wall((0, c), (tip - t / 2, c), (0, -1)), Wall((0, c + t), (tip - t / 2, c + t), (0, 1))]
    hc = c / 2
    nodes = {"A": (_u(rng, 1.2, 3.0), hc), "B": (_u(rng, 1.2, 0.5 * w), h - hc),
             "t0": (w - hc, hc), "t1": (w - hc, h - hc)}
    segments = [("A", "t0"), ("t0", "t1"), ("t1", "B")]
    obstacles = [divider] + _pillars(rng, walls[:2], robot_radius, c)
    tasks = [("A", "B")] if rng.random() < 0.5 else [("A", "B"), ("B", "A")]
    return Layout("u-turn", (w, h), obstacles, walls, nodes, segments, ["A", "B"], tasks, c,
                  [variant, "U-turn", "dead ends"])


def _comb(rng: np.random.Generator, robot_radius: float, cap: float | None) -> Layout:
    if cap is None:
        n = int(rng.integers(2, 4))
        c = _u(rng, 2.2, 3.0)
        w = _u(rng, max(16.0, (n + 1) * (c + 1.0)), 26)
    else:  # n aisles 2.2 m wide or more, each with 1 m of rack beside it, fit in the cap
        n = int(rng.integers(2, min(4, int((cap - 0.04) / 3.2))))
        c = _u(rng, 2.2, min(3.0, cap / (n + 1) - 1.0 - 0.01))   # 0.01: _u rounds to centimetres
        top = min(26.0, cap)
        w = _u(rng, min(max(16.0, SMALL_SIDE * top, (n + 1) * (c + 1.0)), top), top)
    h = _side(rng, 9, 14, cap)
    xs = [round(w * (i + 1) / (n + 1), 2) for i in range(n)]
    polygon_racks = rng.random() < 0.5
    obstacles: list[dict[str, Any]] = []
    walls = [Wall((0, 0), (w, 0), (0, 1)), Wall((0, 0), (0, c), (1, 0)), Wall((w, 0), (w, c), (-1, 0))]
    edges = [0.0] + [v for x in xs for v in (round(x - c / 2, 4), round(x + c / 2, 4))] + [w]
    for left, right in zip(edges[0::2], edges[1::2], strict=True):
        obstacles.append({"polygon": _rect(left, c, right, h)} if polygon_racks else _box(left, c, right, h))
        walls.append(Wall((left, c), (right, c), (0, -1)))
    for x in xs:
        a, b = round(x - c / 2, 4), round(x + c / 2, 4)
        walls += [Wall((a, c), (a, h), (1, 0)), Wall((b, c), (b, h), (-1, 0)), Wall((a, h), (b, h), (0, -1))]
    hc = c / 2
    nodes: dict[str, tuple[float, float]] = {}
    segments: list[tuple[str, str]] = []
    docks = []
    for i, x in enumerate(xs):
        d = f"D{i}"
        nodes[d] = (x, round(h - _u(rng, 1.0, 2.0), 2))
        nodes[f"j{i}"] = (x, hc)
        segments.append((d, f"j{i}"))
        if i:
            segments.append((f"j{i - 1}", f"j{i}"))
        docks.append(d)
    tasks = [("D0", f"D{n - 1}")] if rng.random() < 0.5 else [("D0", f"D{n - 1}"), ("D1", "D0")]
    obstacles += _pillars(rng, walls[:1], robot_radius, c)
    return Layout("comb", (w, h), obstacles, walls, nodes, segments, docks, tasks, c,
                  [f"{n} dead-end aisles", "polygon racks" if polygon_racks else "box racks", "90° corners"])


def _l_hall(rng: np.random.Generator, robot_radius: float, cap: float | None) -> Layout:
    w, h = _side(rng, 14, 24, cap), _side(rng, 10, 18, cap)
    c1, c2 = _u(rng, 2.5, 4.5), _u(rng, 2.5, 4.5)
    ch = _u(rng, 0.3, 1.5)
    filler = {"polygon": [[c2, round(c1 + ch, 4)], [round(c2 + ch, 4), c1], [w, c1], [w, h], [c2, h]]}
    walls = [Wall((0, 0), (w, 0), (0, 1)), Wall((0, 0), (0, h), (1, 0)), Wall((w, 0), (w, c1), (-1, 0)),
             Wall((0, h), (c2, h), (0, -1)), Wall((c2 + ch, c1), (w, c1), (0, -1)),
             Wall((c2, c1 + ch), (c2, h), (-1, 0))]
    nodes = {"A": (round(w - _u(rng, 1.2, 2.5), 2), c1 / 2), "k": (c2 / 2, c1 / 2),
             "B": (c2 / 2, round(h - _u(rng, 1.2, 2.5), 2))}
    obstacles = [filler] + _pillars(rng, walls[:2], robot_radius, min(c1, c2))
    tasks = [("A", "B")] if rng.random() < 0.5 else [("A", "B"), ("B", "A")]
    return Layout("l-hall", (w, h), obstacles, walls, nodes, [("A", "k"), ("k", "B")], ["A", "B"], tasks,
                  min(c1, c2), ["chamfered polygon filler", "90° corner"])


_LAYOUTS = {"loop": _loop, "u-turn": _u_turn, "comb": _comb, "l-hall": _l_hall}


def _markers(rng: np.random.Generator, walls: list[Wall], kind: str, k: int) -> list[dict[str, Any]]:
    """Reflectors along ``walls`` at one spacing, staggered per wall, at most ``MAX_MARKERS[k]``.

    ``kind``: ``post``, ``flat`` (facing along the wall's normal, into the open) or ``mixed``
    (each one flat with probability 1/2).
    """
    usable = [walls[i] for i in rng.permutation(len(walls)) if walls[i].length > 2 * WALL_MARGIN]
    total = sum(wl.length - 2 * WALL_MARGIN for wl in usable)
    spacing = max(total / MAX_MARKERS[k], 2.0 if kind == "post" else 1.5) * float(rng.uniform(1.0, 1.3))
    out: list[dict[str, Any]] = []
    for wl in usable:
        a, b, n = np.array(wl.a, float), np.array(wl.b, float), wl.normal
        free = wl.length - 2 * WALL_MARGIN
        # on average free / spacing reflectors per wall, whatever its length
        count = int(free // spacing) + (1 if rng.random() < (free % spacing) / spacing else 0)
        if count == 0:
            continue
        u0 = float(rng.uniform(0.0, free - (count - 1) * spacing))
        for j in range(count):
            if len(out) >= MAX_MARKERS[k]:
                break
            u = WALL_MARGIN + u0 + j * spacing
            p = a + (b - a) * (u / wl.length)
            flat = kind == "flat" or (kind == "mixed" and rng.random() < 0.5)
            m: dict[str, Any] = {"id": f"R{len(out) + 1}", "position": [round(float(p[0]), 3), round(float(p[1]), 3)]}
            if flat:
                m["kind"] = "flat"
            m["facing_deg"] = round(math.degrees(math.atan2(n[1], n[0])), 1)
            out.append(m)
    return out


def _shift(xy: list[float] | tuple[float, float], origin: tuple[float, float]) -> list[float]:
    return [round(xy[0] + origin[0], 4), round(xy[1] + origin[1], 4)]


def _shift_obstacle(ob: dict[str, Any], origin: tuple[float, float]) -> dict[str, Any]:
    out = dict(ob)
    if "center" in ob:
        out["center"] = _shift(ob["center"], origin)
    if "polygon" in ob:
        out["polygon"] = [_shift(p, origin) for p in ob["polygon"]]
    if "holes" in ob:
        out["holes"] = [[_shift(p, origin) for p in hole] for hole in ob["holes"]]
    return out


def draw_world(rng: np.random.Generator, name: str, *, max_size: float | None = None,
               bounded: bool = False) -> DrawnWorld:
    """Draw one honest world.

    Parameters
    ----------
    rng : numpy.random.Generator
        The world's own stream; the same state gives the same world.
    name : str
        The scenario's ``name``.
    max_size : float, optional
        Cap on the floor's sides [m], at least :data:`SMALLEST_MAX_SIZE` (the caller checks);
        None: the full ranges.
    bounded : bool
        Uniform noise and a set-membership PEF model (``gdop`` drawn becomes ``strips``).

    Returns
    -------
    DrawnWorld
        ``data`` with ``planning.eps_max`` a placeholder (1 m), ``summary`` and ``eps_factor``.
    """
    kind = KINDS[int(rng.integers(len(KINDS)))]
    robot_radius = _u(rng, 0.25, 0.4)
    lay = _LAYOUTS[kind](rng, robot_radius, max_size)
    k = int(rng.integers(2, 5))
    model = (MODELS_K2 if k == 2 else MODELS_K)[int(rng.integers(4 if k == 2 else 3))]
    # flat reflectors are seen only near their normal: k = 4 from them needs more than MAX_MARKERS
    reflectors = ("post", "flat", "mixed")[int(rng.integers(3 if k < 4 else 1))]
    markers = _markers(rng, lay.walls, reflectors, k)
    noise = "uniform" if rng.random() < 0.5 else "gaussian"
    if bounded:
        noise, model = "uniform", "strips" if model == "gdop" else model
    bearing = _sig(_log_u(rng, 0.05, 0.5), 2) if rng.random() < 0.4 else 0.0
    redundancy = 1 if rng.random() < 0.3 else 0
    block = _u(rng, *BLOCK_RANGE) if redundancy else 0.0
    far = rng.random() < 0.5
    origin = (round(float(rng.uniform(-FAR_ORIGIN, FAR_ORIGIN)), 3),
              round(float(rng.uniform(-FAR_ORIGIN, FAR_ORIGIN)), 3)) if far else (0.0, 0.0)
    sensor = {
        "relative_error": _sig(_log_u(rng, *RE_RANGE)),
        "absolute_error": _sig(_log_u(rng, *RHO0_RANGE)),
        "noise": noise,
        "bearing_error_deg": bearing,
        "max_range": _u(rng, 12.0, 30.0, 1),
        "measurement_time": _u(rng, 0.01, 0.04, 3),
        "markers_per_fix": k,
        "fix_rate_hz": _u(rng, 2.0, 8.0, 1),
        "max_incidence_deg": _u(rng, 55.0, 80.0, 0) if reflectors != "post" else 45.0,
        "block_probability": block,
    }
    robot = {
        "wheel_radius": _u(rng, 0.08, 0.12, 3),
        "wheel_base": _u(rng, 0.4, 0.6),
        "radius": robot_radius,
        "max_speed": _u(rng, *SPEED_RANGE),
        "encoder_ticks": int(round(_log_u(rng, *TICKS_RANGE))),
        "wheel_radius_error": _u(rng, 0.0, 0.004, 4),
        "odometry_noise": _u(rng, *SLIP_RANGE, 4),
        "turn_slip": TURN_SLIP,
    }
    robot["wheel_base"] = _fitting_wheel_base(robot)
    eps_factor = _u(rng, *EPS_FACTOR_RANGE)
    seed = int(rng.integers(2**31))
    docks = []
    for d in lay.docks:
        x, y = lay.nodes[d]
        nb = next(b if a == d else a for a, b in lay.segments if d in (a, b))
        yaw = math.degrees(math.atan2(lay.nodes[nb][1] - y, lay.nodes[nb][0] - x))
        docks.append({"name": d, "pose": [*_shift((x, y), origin), round(yaw, 1)]})
    data: dict[str, Any] = {
        "name": name,
        "description": f"random honest world: {kind}, {len(markers)} {reflectors} reflectors, k = {k}, "
                       f"{model}, {noise} noise" + (f", bearings {bearing:g} deg" if bearing else ""),
        "seed": seed,
        "workspace": {"size": [lay.size[0], lay.size[1]], "origin": list(origin)},
        "obstacles": [_shift_obstacle(o, origin) for o in lay.obstacles],
        "markers": [{**m, "position": _shift(m["position"], origin)} for m in markers],
        "sensor": sensor,
        "robot": robot,
        "planning": {"eps_max": 1.0, "pef_model": model, "resolution": 0.1, "redundancy": redundancy},
        "docks": docks,
        "routes": {"nodes": {n: _shift(p, origin) for n, p in lay.nodes.items()},
                   "segments": [list(s) for s in lay.segments]},
        "tasks": [{"from": a, "to": b} for a, b in lay.tasks],
        "montecarlo": {"runs": 200, "success_target": 0.95},
    }
    n_circles = sum("radius" in o for o in lay.obstacles)
    summary = [
        f"layout {kind} {lay.size[0]:g} x {lay.size[1]:g} m, corridors {lay.corridor:g} m: "
        + ", ".join(lay.features) + (f", {n_circles} round pillars" if n_circles else ""),
        f"{len(markers)} {reflectors} reflectors on the walls"
        + (f" (max incidence {sensor['max_incidence_deg']:g} deg)" if reflectors != "post" else ""),
        f"k = {k}, pef_model {model}, {noise} noise, Re {sensor['relative_error']:g}, "
        f"rho0 {sensor['absolute_error'] * 1000:g} mm, bearings " + (f"{bearing:g} deg" if bearing else "off"),
        f"speed {robot['max_speed']:g} m/s, {robot['encoder_ticks']} ticks, slip {robot['odometry_noise']:g}",
        f"origin ({origin[0]:.3f}, {origin[1]:.3f})",
        f"redundancy {redundancy}" + (f", block_probability {block:g}" if redundancy else ""),
        "tasks " + ", ".join(f"{a}->{b}" for a, b in lay.tasks),
    ]
    return DrawnWorld(data=data, summary=summary, eps_factor=eps_factor)
