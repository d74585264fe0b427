"""Loading and validating scenario files (TOML) into :class:`~scenarios.schema.Scenario`.

Every error names the file, the key path and the value, on one line, e.g.
``warehouse.toml: markers[3].position: expected [x, y] inside the workspace, got [31.0, 2.0]``.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from scenarios import floorplan
from scenarios.body import body_reach
from scenarios.errors import ScenarioError, SimulationError
from scenarios.fields import Table, show_path
from scenarios.files import unreadable_because
from scenarios.limits import (
    MAX_CANDIDATES,
    MAX_GRID_CELLS,
    MAX_HEIGHT,
    MAX_HOLD,
    MAX_MARKERS,
    MAX_NESTING,
    MAX_PATH_SAMPLES,
    MAX_PEF_PASSES,
    MAX_ROBOT_TASKS,
    MAX_ROBOTS,
    MAX_RUNS,
    MAX_SCENARIO_BYTES,
    MIN_GRID_CELLS,
    SAMPLES_PER_FIX,
    long_integer,
    nesting_depth,
)
from scenarios.obstacle_table import read_obstacle
from scenarios.routegraph import place_node_docks, portable_routes_text, read_node_dock, read_routes
from scenarios.schema import (
    Dock,
    FleetRobot,
    Marker,
    MarkerKind,
    MonteCarloSpec,
    NoiseModel,
    PefModel,
    PlacementSpec,
    PlanningSpec,
    RobotSpec,
    Scenario,
    SensorSpec,
    Task,
    Weights,
    Workspace,
)

LIBRARY = Path(__file__).resolve().parent / "library"

#: Limits of the loader, each with its reason (values beyond them are typos or unit mistakes,
#: and would otherwise surface as overflows, memory errors or hour-long runs downstream); the
#: budgets shared with the readers and the planner are in :mod:`scenarios.limits`.
MAX_EPS = 100.0
"""Largest eps_max [m]: an allowed error beyond 100 m is not a positioning question."""
MAX_RANGE = 10_000.0
"""Largest sensor.max_range [m]: no laser ranges reflectors 10 km away."""
MAX_MARKERS_PER_FIX = 8
"""Largest k: the PEF scores every k-subset of the markers, C(M, k) of them."""
MIN_SPACING = 0.01
"""Smallest placement.spacing [m]: finer sampling only multiplies the candidate sites."""
MAX_SEED = 2**63 - 1
"""Largest ``seed``: a signed 64-bit integer, which every table and tool downstream keeps exactly
(``pefsim worlds`` draws seeds below 2**31)."""
CRITERIA = tuple(f.name for f in fields(Weights))


def builtin_names() -> list[str]:
    """Names of the built-in scenarios (files in ``scenarios/library``), sorted."""
    return sorted(p.stem for p in LIBRARY.glob("*.toml"))


def resolve(name_or_path: str | Path) -> Path:
    """Return the path of a scenario given as a path or a built-in name."""
    p = Path(name_or_path)
    why = unreadable_because(p)
    if why is None:
        return p
    if p.suffix == ".toml" or why != "no such file":  # a path, not a built-in name
        if why == "no such file":
            why = "no such scenario file"
        raise ScenarioError(f"{show_path(p)}: cannot read: {why}" if why != "no such scenario file"
                            else f"{show_path(p)}: {why}")
    candidate = LIBRARY / f"{name_or_path}.toml"
    if candidate.is_file():
        return candidate
    raise ScenarioError(
        f"{name_or_path}: not a file and not a built-in scenario (built-in: {', '.join(builtin_names())})")


def load(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario from a path or a built-in name."""
    path = resolve(name_or_path)
    try:
        size = path.stat().st_size
        if size > MAX_SCENARIO_BYTES:  # parsing takes seconds a megabyte: refused before it is read
            raise ScenarioError(f"{show_path(path)}: a scenario of {size} bytes, at most {MAX_SCENARIO_BYTES:.0e}")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot read: {exc}") from None
    # Errors name the file as the user gave it; a built-in one by its file name alone.
    shown = path.name if path.parent == LIBRARY else str(name_or_path)
    sc = loads(text, source=shown, base=path.parent)
    return replace(sc, files=(path.resolve(), *sc.files))


def loads(text: str, source: str = "<string>", base: Path | None = None) -> Scenario:
    """Parse and validate scenario TOML ``text``; ``source`` names it in errors, ``base`` is its folder.

    Relative file names in the scenario (``floorplan.file``, ``routes.file``) are taken from ``base`` (None: the
    current directory); ``Scenario.text`` names them absolutely, since it is stored beside
    results and loaded again from there.
    """
    text = text.removeprefix("\ufeff")  # a byte-order mark is legal at the start of UTF-8 text (Windows editors)
    depth = nesting_depth(text)
    if depth > MAX_NESTING:  # tomllib recurses per level: refused before it parses
        raise ScenarioError(f"{source}: arrays and tables nested {depth} deep, at most {MAX_NESTING}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: malformed TOML: {exc}") from None
    except ValueError:  # Python's int-string limit (4300 digits): no number of a scenario is that long
        raise ScenarioError(f"{source}: malformed TOML: {long_integer(text)}") from None
    # Scenario.text names relative files (floor plan, route graph) absolutely: it is stored beside
    # results and loaded again from there.
    portable = floorplan.portable_text(text, data, base)
    portable = portable_routes_text(portable, data if portable is text else tomllib.loads(portable), base)
    return replace(from_dict(data, source, base), text=portable)


def _sensor(t: Table, base: SensorSpec, required: bool) -> SensorSpec:
    """Read a [sensor] table; with ``required`` False every key is an override of ``base``."""
    d = base if not required else SensorSpec()
    noise = t.string("noise", d.noise.value, choices=tuple(m.value for m in NoiseModel))
    spec = SensorSpec(
        relative_error=t.number("relative_error", d.relative_error, low=0.0, high=0.5),
        absolute_error=t.number("absolute_error", d.absolute_error, low=0.0, high=10.0),
        noise=NoiseModel(noise),
        bearing_error=math.radians(t.number("bearing_error_deg", math.degrees(d.bearing_error),
                                            low=0.0, high=45.0)),
        max_range=t.number("max_range", d.max_range, low=0.0, low_open=True, high=MAX_RANGE),
        measurement_time=t.number("measurement_time", d.measurement_time, low=0.0, high=60.0),
        markers_per_fix=t.integer("markers_per_fix", d.markers_per_fix, low=2, high=MAX_MARKERS_PER_FIX),
        fix_rate_hz=t.number("fix_rate_hz", d.fix_rate_hz, low=0.0, low_open=True, high=1000.0),
        max_incidence=math.radians(t.number("max_incidence_deg", math.degrees(d.max_incidence),
                                            low=0.0, low_open=True, high=90.0)),
        block_probability=t.number("block_probability", d.block_probability, low=0.0, high=1.0),
    )
    if spec.relative_error == 0.0 and spec.absolute_error == 0.0:
        t.fail(t.key("absolute_error"), "expected relative_error or absolute_error > 0", 0.0)
    return spec


def _robot(t: Table, base: RobotSpec) -> RobotSpec:
    pos = {"low": 0.0, "low_open": True}
    # upper limits far beyond any wheeled robot: larger values are typos (or unit mistakes)
    spec = RobotSpec(
        wheel_radius=t.number("wheel_radius", base.wheel_radius, high=10.0, **pos),
        wheel_base=t.number("wheel_base", base.wheel_base, high=100.0, **pos),
        radius=t.number("radius", base.radius, high=100.0, **pos),
        max_speed=t.number("max_speed", base.max_speed, high=100.0, **pos),
        max_yaw_rate=t.number("max_yaw_rate", base.max_yaw_rate, high=100.0, **pos),
        encoder_ticks=t.integer("encoder_ticks", base.encoder_ticks, low=1, high=10**9),
        wheel_radius_error=t.number("wheel_radius_error", base.wheel_radius_error, low=-0.2, high=0.2),
        odometry_noise=t.number("odometry_noise", base.odometry_noise, low=0.0, high=0.5),
        turn_slip=t.number("turn_slip", base.turn_slip, low=-0.5, high=0.5),
        mass=t.number("mass", base.mass, high=1e6, **pos),
        max_wheel_torque=t.number("max_wheel_torque", base.max_wheel_torque, high=1e6, **pos),
        height=t.number("height", base.height, high=MAX_HEIGHT, **pos),
    )
    # The laser sits on top of the body: below the wheels' top it would look through them.
    wheels = 2.0 * spec.wheel_radius * (1.0 + abs(spec.wheel_radius_error))
    if spec.height <= wheels:
        t.fail(t.key("height"), f"expected a body taller than its wheels ({wheels:.3g} m: the laser sits on top)",
               spec.height)
    return spec


def _check_body(t: Table, declared: RobotSpec, actual: RobotSpec, actual_t: Table | None) -> None:
    """Refuse a declared ``radius`` that does not contain the simulated body (:mod:`scenarios.body`).

    The planner keeps a disc of the declared radius clear of obstacles; the simulation builds
    the body from the actual spec (and the declared robot's body must fit too: it is the one a
    scenario without ``actual`` simulates). ``t`` is the table holding the declared radius,
    ``actual_t`` the one overriding the simulated robot (None without it).
    """
    for spec, table, what in ((declared, t, ""), (actual, actual_t, " simulated")):
        if table is None and spec is not declared:
            continue
        try:
            reach = body_reach(spec)
        except SimulationError as exc:
            key = "wheel_base" if "wheel_base" in str(exc) else "wheel_radius_error"
            (table or t).fail((table or t).key(key), str(exc).split(": ", 1)[1])
        if reach.distance > declared.radius:
            raise ScenarioError(f"{t.file}: {t.key('radius')}: {declared.radius:g} is smaller than the{what} "
                                f"robot's body, whose {reach.part}")


#: Keys of a ``[[robots]]`` table besides the robot keys it may override.
_FLEET_KEYS = ("name", "tasks", "start_time", "start_jitter", "dwell", "speed_spread", "park", "actual")


def _robots(root: Table, robot: RobotSpec, robot_actual: RobotSpec, tasks: list[Task], workspace: Workspace,
            fix_rate_hz: float, dock_names: set[str] = frozenset()) -> tuple[FleetRobot, ...]:
    """Read the ``[[robots]]`` tables: a fleet in one world (empty: one robot, as without them).

    Each table names the robot, the tasks it drives in order (indices into ``[[tasks]]``, each
    starting at the dock the previous one ended at), its start time, and overrides any key of
    ``[robot]`` (and, in its ``actual`` table, of the simulated robot).
    """
    tables = root.array_of_tables("robots")
    if len(tables) > MAX_ROBOTS:
        root.fail(root.key("robots"), f"expected at most {MAX_ROBOTS} robots", f"{len(tables)} tables")
    fleet: list[FleetRobot] = []
    for t in tables:
        name = t.string("name")
        if not name:
            t.fail(t.key("name"), "expected a non-empty robot name", name)
        if any(f.name == name for f in fleet):
            t.fail(t.key("name"), "expected a unique robot name", name)
        idx = t.raw("tasks")
        if (not isinstance(idx, list) or not idx or len(idx) > MAX_ROBOT_TASKS
                or any(isinstance(i, bool) or not isinstance(i, int) for i in idx)):
            t.fail(t.key("tasks"), f"expected a non-empty list of at most {MAX_ROBOT_TASKS} task indices", idx)
        for j, i in enumerate(idx):
            if not 0 <= i < len(tasks):
                t.fail(f"{t.key('tasks')}[{j}]", f"expected a task index in 0..{len(tasks) - 1} "
                       f"(the scenario has {len(tasks)} [[tasks]])", i)
            if j and tasks[i].start != tasks[idx[j - 1]].goal:
                t.fail(f"{t.key('tasks')}[{j}]", f"expected a task starting at dock {tasks[idx[j - 1]].goal!r} "
                       f"where task {idx[j - 1]} ends (task {i} starts at {tasks[i].start!r})", i)
        start_time = t.number("start_time", 0.0, low=0.0, high=1e6)
        # the run-to-run timing spread (planner.fleet.timing): release delay, dwell, slower speed
        start_jitter = t.number("start_jitter", 0.0, low=0.0, high=3600.0)
        dwell = t.number("dwell", 0.0, low=0.0, high=3600.0)
        speed_spread = t.number("speed_spread", 0.0, low=0.0, high=0.5)
        # where it goes after its last task if it would stand in another robot's way there
        park = t.string("park") if t.has("park") else None
        if park is not None and park not in dock_names:
            t.fail(t.key("park"), "expected a dock name (" + ", ".join(sorted(dock_names)) + ")", park)
        if park is not None and park == tasks[idx[-1]].goal:
            t.fail(t.key("park"), f"expected a dock other than {park!r}, where the robot's last task ends", park)
        declared = _robot(t, robot)
        actual = _robot(t, robot_actual)
        if t.has("actual"):
            a_t = t.table("actual")
            actual = _robot(a_t, actual)
            a_t.done()
            _check_path_samples(a_t, actual, workspace, fix_rate_hz)
        _check_body(t, declared, actual, t.table("actual") if t.has("actual") else t)
        _check_path_samples(t, declared, workspace, fix_rate_hz)
        for key in t.data:
            if key not in _FLEET_KEYS and key not in t.used:
                t.fail(t.key(key), "unknown key (a [[robots]] table takes name, tasks, start_time, start_jitter, "
                       "dwell, speed_spread, park, actual and [robot] keys)", t.data[key])
        t.done()
        fleet.append(FleetRobot(name, tuple(int(i) for i in idx), start_time, declared, actual, start_jitter,
                                dwell, speed_spread, park))
    return tuple(fleet)


def _planning(t: Table) -> PlanningSpec:
    d = PlanningSpec()
    model = t.string("pef_model", d.pef_model.value, choices=tuple(m.value for m in PefModel))
    w = t.table("weights", {})
    weights = Weights(**{c: w.number(c, getattr(Weights(), c), low=0.0, high=1e6) for c in CRITERIA})
    w.done()
    order = t.raw("order", [])
    if not isinstance(order, list) or any(o not in CRITERIA for o in order):
        t.fail(t.key("order"), "expected a list of criteria among " + ", ".join(CRITERIA), order)
    return PlanningSpec(
        eps_max=t.number("eps_max", low=0.0, low_open=True, high=MAX_EPS),
        pef_model=PefModel(model),
        gdop_level=t.number("gdop_level", d.gdop_level, low=0.0, low_open=True, high=0.999999),
        resolution=t.number("resolution", d.resolution, low=0.0, low_open=True),
        weights=weights,
        order=tuple(order),
        heading_std_deg=t.number("heading_std_deg", d.heading_std_deg, low=0.0, high=90.0),
        min_fix_speed=t.number("min_fix_speed", d.min_fix_speed, low=0.0, low_open=True, high=100.0),
        redundancy=t.integer("redundancy", d.redundancy, low=0),
    )


def _check_grid(t: Table, workspace: Workspace, resolution: float) -> None:
    """Refuse a ``planning.resolution`` giving fewer than 2 cells along a side or too many cells in all."""
    w, h = workspace.size
    per_side = [extent / resolution for extent in (w, h)]  # floats: 1e-320 gives inf, not an OverflowError
    if min(round(n) if n < 1e18 else n for n in per_side) < MIN_GRID_CELLS:
        t.fail(t.key("resolution"), f"expected a cell size giving at least {MIN_GRID_CELLS} cells along each side "
               f"of the {w:g} x {h:g} m workspace (at most {min(w, h) / (MIN_GRID_CELLS - 0.5):.3g} m)", resolution)
    cells = per_side[0] * per_side[1]
    if cells > MAX_GRID_CELLS:
        t.fail(t.key("resolution"), f"expected a cell size giving at most {MAX_GRID_CELLS:.0e} grid cells "
               f"over the {w:g} x {h:g} m workspace ({cells:.3g} cells)", resolution)


def _check_redundancy(t: Table, redundancy: int, k: int) -> None:
    """Refuse a redundancy r whose k^r plain PEF passes per point exceed :data:`MAX_PEF_PASSES`."""
    most = int(math.floor(math.log(MAX_PEF_PASSES) / math.log(k) + 1e-9))
    if redundancy > most:
        passes = f"{k}^{redundancy}" if redundancy > 60 else f"{k ** redundancy:.3g}"
        t.fail(t.key("redundancy"), f"expected at most {most} with sensor.markers_per_fix = {k} "
               f"(k^r = {passes} PEF passes per point, at most {MAX_PEF_PASSES})", redundancy)


def _check_path_samples(t: Table, robot: RobotSpec, workspace: Workspace, fix_rate_hz: float) -> None:
    """Refuse speeds so slow that a path across the workspace needs more than MAX_PATH_SAMPLES samples.

    The planner samples a path at least :data:`~scenarios.limits.SAMPLES_PER_FIX` times per fix
    interval; crossing the workspace (width + height, an L-shaped route) at ``max_speed`` and a
    full turn on the spot at ``max_yaw_rate`` each must fit in the budget.
    """
    per_second = SAMPLES_PER_FIX * fix_rate_hz
    crossing = sum(workspace.size)
    for key, value, seconds, what in (
            ("max_speed", robot.max_speed, crossing / robot.max_speed, f"a {crossing:g} m crossing of the workspace"),
            ("max_yaw_rate", robot.max_yaw_rate, 2.0 * math.pi / robot.max_yaw_rate, "a full turn")):
        samples = seconds * per_second
        if samples > MAX_PATH_SAMPLES:
            floor = value * samples / MAX_PATH_SAMPLES
            t.fail(t.key(key), f"expected at least {floor:.3g} ({what} takes {samples:.3g} path samples at "
                   f"{SAMPLES_PER_FIX} per fix at {fix_rate_hz:g} Hz, at most {MAX_PATH_SAMPLES:.0e})", value)


def from_dict(data: dict[str, Any], source: str = "<dict>", base: Path | None = None) -> Scenario:
    """Validate a parsed TOML document and build the :class:`Scenario` (``base``: its folder)."""
    data, plan = floorplan.apply(data, source, base)  # [floorplan] -> obstacles, markers, workspace
    root = Table(data, source)
    name = root.string("name")
    if not name.strip():
        root.fail(root.key("name"), "expected a non-empty name", name)
    seed = root.integer("seed", 0, low=0, high=MAX_SEED)
    description = root.string("description", "")

    ws_t = root.table("workspace")
    walls = ws_t.raw("walls", True)
    if not isinstance(walls, bool):
        ws_t.fail(ws_t.key("walls"), "expected true or false", walls)
    workspace = Workspace(ws_t.vector("size", 2, what="[width, height] in metres", positive=True),
                          origin=ws_t.vector("origin", 2, (0.0, 0.0), what="[x0, y0] in metres"), walls=walls)
    ws_t.done()

    obstacles = [read_obstacle(t) for t in root.array_of_tables("obstacles")]
    unknown = [read_obstacle(t) for t in root.array_of_tables("unknown")]

    def free_point(t: Table, key: str, value: tuple[float, ...], what: str) -> None:
        p = value[:2]  # a dock's value is (x, y, yaw): only the position must be free
        if not workspace.contains(p):
            t.fail(t.key(key), f"expected {what} inside the workspace", list(value))
        for j, ob in enumerate(obstacles):
            if ob.contains(p, margin=-1e-6):
                t.fail(t.key(key), f"expected {what} outside obstacles (inside obstacles[{j}])", list(value))
        for j, ob in enumerate(unknown):
            if ob.contains(p, margin=-1e-6):
                t.fail(t.key(key), f"expected {what} outside unknown areas (inside unknown[{j}])", list(value))

    markers: list[Marker] = []
    marker_tables = root.array_of_tables("markers")
    if len(marker_tables) > MAX_MARKERS:  # before the tables are read: C(M, k) subsets would follow
        drawn = f" (with the reflectors of {plan.file.name})" if plan is not None else ""
        root.fail(root.key("markers"), f"expected at most {MAX_MARKERS} markers (the PEF scores C(M, k) subsets, "
                  f"at most 2e6){drawn}", len(marker_tables))
    ids: set[str] = set()
    for t in marker_tables:
        mid = t.string("id")
        pos = t.vector("position", 2, what="[x, y]")
        free_point(t, "position", pos, "[x, y]")
        if mid in ids:
            t.fail(t.key("id"), "expected a unique marker id", mid)
        ids.add(mid)
        facing = t.number("facing_deg", None) if t.has("facing_deg") else None
        kind = MarkerKind(t.string("kind", MarkerKind.POST.value, choices=tuple(k.value for k in MarkerKind)))
        if kind is MarkerKind.FLAT and facing is None:
            t.fail(t.key("facing_deg"), "expected the normal's direction in degrees for a flat marker (missing)")
        height = t.number("height", None, low=0.0, low_open=True, high=MAX_HEIGHT) if t.has("height") else None
        markers.append(Marker(mid, pos, None if facing is None else math.radians(facing), kind, height))
        t.done()

    s_t = root.table("sensor")
    sensor = _sensor(s_t, SensorSpec(), required=True)
    sensor_actual = sensor
    if s_t.has("actual"):
        a_t = s_t.table("actual")
        sensor_actual = _sensor(a_t, sensor, required=False)
        a_t.done()
    s_t.done()
    # No markers at all is a world still to be equipped (pefsim place); a few is a typo.
    if 0 < len(markers) < sensor.markers_per_fix:
        s_t.fail(s_t.key("markers_per_fix"),
                 f"expected at most the number of markers ({len(markers)})", sensor.markers_per_fix)

    r_t = root.table("robot", {})
    robot = _robot(r_t, RobotSpec())
    robot_actual = robot
    if r_t.has("actual"):
        a_t = r_t.table("actual")
        robot_actual = _robot(a_t, robot)
        a_t.done()
    r_t.done()
    _check_body(r_t, robot, robot_actual, r_t.table("actual") if r_t.has("actual") else None)

    p_t = root.table("planning")
    planning = _planning(p_t)
    p_t.done()
    _check_grid(p_t, workspace, planning.resolution)
    _check_redundancy(p_t, planning.redundancy, sensor.markers_per_fix)
    for table, spec in ((r_t, robot), (r_t.table("actual") if r_t.has("actual") else None, robot_actual)):
        if table is not None:
            _check_path_samples(table, spec, workspace, sensor.fix_rate_hz)
    if planning.pef_model is PefModel.PARALLELOGRAM and sensor.markers_per_fix != 2:
        p_t.fail(p_t.key("pef_model"),
                 f"parallelogram needs sensor.markers_per_fix = 2 (use \"strips\" for k = {sensor.markers_per_fix})",
                 planning.pef_model.value)

    docks, dock_tables = [], root.array_of_tables("docks")
    for t in dock_tables:
        dname = t.string("name")
        if any(d.name == dname for d in docks):
            t.fail(t.key("name"), "expected a unique dock name", dname)
        if t.has("node"):  # placed on its node once the routes are read
            docks.append(read_node_dock(t, dname))
            t.done()
            continue
        pose = t.vector("pose", 3, what="[x, y, yaw_deg]")
        free_point(t, "pose", pose, "[x, y, yaw_deg]")
        docks.append(Dock(dname, (pose[0], pose[1], math.radians(pose[2]))))
        t.done()
    dock_names = {d.name for d in docks}

    routes = None
    if root.has("routes"):
        routes = read_routes(root.table("routes"), workspace=workspace, obstacles=obstacles + unknown,
                             radius=robot.radius, docks=docks, free_point=free_point,
                             base_dir=None if base is None else Path(base))
    docks = place_node_docks(docks, dock_tables, routes, free_point)

    tasks = []
    for t in root.array_of_tables("tasks"):
        a, b = t.string("from"), t.string("to")
        for key, v in (("from", a), ("to", b)):
            if v not in dock_names:
                t.fail(t.key(key), "expected a dock name (" + ", ".join(sorted(dock_names)) + ")", v)
        if a == b:
            t.fail(t.key("to"), "expected a dock other than 'from'", b)
        tasks.append(Task(a, b))
        t.done()

    robots = _robots(root, robot, robot_actual, tasks, workspace, sensor.fix_rate_hz, dock_names)

    mc_t = root.table("montecarlo", {})
    montecarlo = MonteCarloSpec(
        runs=mc_t.integer("runs", MonteCarloSpec().runs, low=1, high=MAX_RUNS),
        success_target=mc_t.number("success_target", MonteCarloSpec().success_target, low=0.0, high=1.0),
        hold=mc_t.number("hold", MonteCarloSpec().hold, low=0.0, high=MAX_HOLD),
    )
    mc_t.done()

    pl_t = root.table("placement", {})
    cands = []
    raw_cands = pl_t.raw("candidates", [])
    if isinstance(raw_cands, list) and len(raw_cands) > MAX_CANDIDATES:
        pl_t.fail(pl_t.key("candidates"), f"expected at most {MAX_CANDIDATES} candidate sites", len(raw_cands))
    for i, c in enumerate(raw_cands):
        key = f"{pl_t.key('candidates')}[{i}]"
        p = pl_t.check_vector(key, c, 2, what="[x, y]")
        if not workspace.contains(p):
            pl_t.fail(key, "expected [x, y] inside the workspace", list(p))
        cands.append(p)
    placement = PlacementSpec(
        candidates=tuple(cands),
        spacing=pl_t.number("spacing", PlacementSpec().spacing, low=MIN_SPACING),
        cover=pl_t.string("cover", PlacementSpec().cover, choices=("routes", "free")),
        marker_kind=MarkerKind(pl_t.string("marker_kind", PlacementSpec().marker_kind.value,
                                           choices=tuple(k.value for k in MarkerKind))),
        existing=pl_t.string("existing", PlacementSpec().existing, choices=("replace", "keep")),
    )
    pl_t.done()
    root.done()

    return Scenario(
        name=name, seed=seed, description=description, workspace=workspace,
        obstacles=tuple(obstacles), markers=tuple(markers), sensor=sensor,
        sensor_actual=sensor_actual, robot=robot, robot_actual=robot_actual, planning=planning,
        docks=tuple(docks), routes=routes, tasks=tuple(tasks), montecarlo=montecarlo,
        placement=placement, source=source, floorplan=plan, robots=robots, unknown=tuple(unknown),
        files=(*(plan.files if plan is not None else ()),
               *((routes.file,) if routes is not None and routes.file is not None else ())),
    )


def with_overrides(scenario: Scenario, **changes: Any) -> Scenario:
    """Return a copy of ``scenario`` with top-level fields replaced (for tests and sweeps)."""
    return replace(scenario, **changes)
