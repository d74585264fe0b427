"""The scenario model: frozen dataclasses for every part of a scenario file.

Units are SI throughout (metres, seconds, radians). Files may give angles in degrees where
the key ends in ``_deg``; the loader converts them, so every angle held here is in radians.
Construction does not validate: :mod:`scenarios.load` checks every value against the file
and key it came from before building these objects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from functools import cached_property
from pathlib import Path

import numpy as np

from scenarios.floorplan.spec import FloorPlan
from scenarios.obstacles import ConvexPieces, Obstacle, pack_pieces
from scenarios.route_network import RouteNetwork


class NoiseModel(str, Enum):
    """How range (and bearing) errors are realised in simulation.

    ``uniform``: uniform in ±ρ (the paper's bounded, set-membership view).
    ``gaussian``: normal with σ = ρ/3.
    """

    UNIFORM = "uniform"
    GAUSSIAN = "gaussian"


class PefModel(str, Enum):
    """The error model that turns a marker subset into a predicted error τ (metres).

    ``exact``: diameter of the exact fault area (intersection of annuli), by polygon clipping.
    ``parallelogram``: long diagonal of the linearised two-marker parallelogram (k = 2).
    ``strips``: diameter of the intersection of k linearised strips.
    ``gdop``: major axis (diameter) of the p-level confidence ellipse of the least-squares fix.
    """

    EXACT = "exact"
    PARALLELOGRAM = "parallelogram"
    STRIPS = "strips"
    GDOP = "gdop"


@dataclass(frozen=True)
class Workspace:
    """Rectangular workspace, x right, y up, in the user's frame.

    ``size`` = (width, height) [m]; ``origin`` = (x0, y0), its lower-left corner [m] (every
    position of a scenario, and every output, is in that frame). ``walls``: its border is a
    wall (a physics body, a face for reflectors); a ROS map's is not (the image edge is no wall:
    only its occupied cells are), and routes still stay inside it.
    """

    size: tuple[float, float]
    origin: tuple[float, float] = (0.0, 0.0)
    walls: bool = True

    @property
    def width(self) -> float:
        return self.size[0]

    @property
    def height(self) -> float:
        return self.size[1]

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1): lower-left and upper-right corners [m]."""
        x0, y0 = self.origin
        return (x0, y0, x0 + self.size[0], y0 + self.size[1])

    def contains(self, p: tuple[float, float] | np.ndarray) -> bool:
        """Tell whether point ``p`` (x, y) [m] lies in the closed workspace rectangle.

        A point on the far walls may miss ``origin + size`` by a rounding (a marker at
        x = 250030.1 with the origin at 250000 and a width of 30.1): a few units in the last
        place of the coordinates, plus a nanometre, count as on the wall.
        """
        x0, y0, x1, y1 = self.bounds
        tol = 1e-9 + 4.0 * float(np.spacing(max(abs(x0), abs(y0), abs(x1), abs(y1))))
        return x0 - tol <= p[0] <= x1 + tol and y0 - tol <= p[1] <= y1 + tol


class MarkerKind(str, Enum):
    """How a reflector can be seen.

    ``post``: a round post, seen from every side.
    ``flat``: a flat reflector (tape on a wall or a rack face), seen only from the points whose
    direction from it is within ``sensor.max_incidence_deg`` of its normal ``facing``.
    """

    POST = "post"
    FLAT = "flat"


@dataclass(frozen=True)
class Marker:
    """A landmark (laser reflector, anchor) at a known ``position`` (x, y) [m].

    ``facing`` [rad] is the direction the reflector faces (file key ``facing_deg``; a DXF
    block's rotation), None when not given; a ``flat`` marker always has one.
    """

    id: str
    position: tuple[float, float]
    facing: float | None = None
    kind: MarkerKind = MarkerKind.POST
    height: float | None = None
    """Height of the reflector's centre above the floor [m]; None: above every robot, so that
    no robot ever hides it (a fleet's robots block only the lines of sight to reflectors mounted
    lower than they are tall, see :attr:`RobotSpec.height`)."""

    @property
    def normal(self) -> tuple[float, float]:
        """Unit normal (cos facing, sin facing) of a flat marker; (0, 0) for a post."""
        if self.kind is not MarkerKind.FLAT or self.facing is None:
            return (0.0, 0.0)
        return (math.cos(self.facing), math.sin(self.facing))


@dataclass(frozen=True)
class SensorSpec:
    """The laser marker sensor.

    Attributes
    ----------
    relative_error : float
        Re, range error bound per metre of range [m/m].
    absolute_error : float
        ρ0, range error bound independent of range [m].
    noise : NoiseModel
        How errors are realised in simulation.
    bearing_error : float
        ξ, bound of the bearing error [rad]; 0 means ranges only.
    max_range : float
        Markers farther than this cannot be measured [m].
    measurement_time : float
        Time one marker measurement takes [s]; the robot moves meanwhile.
    markers_per_fix : int
        k, markers measured per fix.
    fix_rate_hz : float
        Highest rate at which fixes can start [Hz].
    max_incidence : float
        A flat marker is seen only within this angle of its normal [rad] (file key
        ``max_incidence_deg``, in (0, 90]).
    block_probability : float
        Simulation only: chance that a scheduled marker's line of sight is blocked at a fix
        (a person, a pallet), independently per marker and fix [-].
    """

    relative_error: float = 6.7e-5
    absolute_error: float = 0.002
    noise: NoiseModel = NoiseModel.UNIFORM
    bearing_error: float = 0.0
    max_range: float = 25.0
    measurement_time: float = 0.02
    markers_per_fix: int = 2
    fix_rate_hz: float = 5.0
    max_incidence: float = math.radians(45.0)
    block_probability: float = 0.0

    @property
    def cos_incidence(self) -> float:
        """Cos of :attr:`max_incidence`, the flat-marker test's threshold [-]."""
        return math.cos(self.max_incidence)

    def range_bound(self, r: np.ndarray | float) -> np.ndarray | float:
        """ρ(r) = Re·r + ρ0 [m], the bound of the range error at range ``r`` [m]."""
        return self.relative_error * r + self.absolute_error

    def measured_range_bound(self, r_measured: np.ndarray | float) -> np.ndarray | float:
        """Bound of the range error of a *measured* range ``r_measured`` [m].

        ρ is declared at the true range, ``|e| <= Re (r̃ - e) + ρ0``: a range measured short by
        nearly ρ has ``Re r̃ + ρ0`` too small by ``Re ρ`` (0.17 µm at 8 m, and a truth that far
        outside its fault area). Solved for ``|e|``: ``(Re r̃ + ρ0) / (1 - Re)``.
        """
        return (self.relative_error * r_measured + self.absolute_error) / (1.0 - self.relative_error)

    @property
    def uses_bearing(self) -> bool:
        return self.bearing_error > 0.0


@dataclass(frozen=True)
class RobotSpec:
    """A differential-drive robot.

    Attributes
    ----------
    wheel_radius : float
        Nominal wheel radius [m].
    wheel_base : float
        Distance between the wheel contact points [m].
    radius : float
        Radius of the robot's footprint, used to inflate obstacles [m].
    max_speed : float
        Highest forward speed [m/s].
    max_yaw_rate : float
        Highest turning rate [rad/s].
    encoder_ticks : int
        Encoder ticks per wheel revolution (odometry quantisation).
    wheel_radius_error : float
        Systematic relative error of the right wheel's radius against the nominal one (the
        left wheel has the opposite sign), the classic UMBmark odometry error [-].
    odometry_noise : float
        Relative standard deviation of each wheel's travelled distance per increment
        (slip, floor), used by the filter's process noise [-]. The simulation draws it normal,
        or, in a bounded-noise world (``sensor.noise = "uniform"``), uniform within
        ``+-sqrt(3)`` of it (every random error of that world has a bound).
    turn_slip : float
        Outward (sideways) slip of the axle midpoint over one odometry step per metre of travel
        and radian of the step's heading change [-]: the step's chord points along
        ``theta + (1/2 - turn_slip) dtheta`` instead of the arc's ``theta + dtheta/2``
        (a slip angle of ``turn_slip * omega * T`` at yaw rate omega, odometry period T).
        The default is the simulated robot's, measured (:mod:`estimators.motion`): the physics
        slips so whatever is declared, so a scenario that left it out at 0 declared a filter
        overconfident in turns.
    mass : float
        Chassis mass [kg].
    max_wheel_torque : float
        Torque limit of each wheel motor [N m].
    height : float
        Height of the robot's body above the floor [m]; in a fleet its laser sits on top (a lone
        robot's laser stays at ``PhysicsConfig.laser_height``, 0.5 m). 0.5 m is the
        height the laser had in every episode before robots had a height (and a usual height of
        an AGV's top-mounted reflector laser, which must look over loads and people's legs).
        In a fleet a robot's body (a cylinder of ``radius`` and ``height``) blocks the other
        robots' lines of sight to reflectors mounted below its top.
    """

    wheel_radius: float = 0.1
    wheel_base: float = 0.5
    radius: float = 0.4
    max_speed: float = 1.0
    max_yaw_rate: float = 1.5
    encoder_ticks: int = 2048
    wheel_radius_error: float = 0.002
    odometry_noise: float = 0.01
    turn_slip: float = 0.13
    mass: float = 20.0
    max_wheel_torque: float = 20.0
    height: float = 0.5


@dataclass(frozen=True)
class Weights:
    """Weights of the route criteria (normalised criteria are multiplied by these)."""

    accuracy: float = 1.0
    length: float = 1.0
    traffic: float = 0.5
    clearance: float = 0.5
    smoothness: float = 0.1


@dataclass(frozen=True)
class PlanningSpec:
    """Planning parameters: ``eps_max`` [m], PEF model, GDOP probability, grid resolution [m]."""

    eps_max: float = 0.05
    pef_model: PefModel = PefModel.PARALLELOGRAM
    gdop_level: float = 0.95
    resolution: float = 0.1
    weights: Weights = field(default_factory=Weights)
    order: tuple[str, ...] = ()
    """Lexicographic criteria order; empty means weighted sum."""
    heading_std_deg: float = 0.3
    """Heading std of the filter the promise of a moving fix assumes [deg] (it turns the
    odometry shift of the fix's earlier ranges, :mod:`estimators.fault.carried`)."""
    min_fix_speed: float = 0.05
    """Slowest speed the planner may slow down to for a fix [m/s]."""
    redundancy: int = 0
    """r: markers that may be blocked without breaking the promise (tau_r, `docs/design.md` §1)."""

    @property
    def heading_std(self) -> float:
        """:attr:`heading_std_deg` in radians."""
        return math.radians(self.heading_std_deg)


@dataclass(frozen=True)
class Dock:
    """A named pose: ``pose`` = (x [m], y [m], yaw [rad]).

    ``node`` names the route-network node the dock sits on (``[[docks]] node = "12"``), None
    for a dock given by its pose; routes to and from the dock start at that node.
    """

    name: str
    pose: tuple[float, float, float]
    node: str | None = None

    @property
    def position(self) -> tuple[float, float]:
        return (self.pose[0], self.pose[1])


@dataclass(frozen=True)
class Task:
    """An episode's errand: drive from dock ``start`` to dock ``goal`` (TOML keys ``from``/``to``)."""

    start: str
    goal: str


@dataclass(frozen=True)
class FleetRobot:
    """One robot of a fleet (a ``[[robots]]`` table).

    Attributes
    ----------
    name : str
        Unique name of the robot.
    tasks : tuple of int
        Indices into ``Scenario.tasks`` driven one after another; each task starts at the dock
        the previous one ended at.
    start_time : float
        When the robot leaves its first dock [s]; it stands on that dock until then.
    robot : RobotSpec
        The declared robot: the scenario's ``[robot]`` with this robot's overrides applied
        (planner and filter use it).
    robot_actual : RobotSpec
        The simulated robot: the scenario's ``[robot.actual]`` with this robot's overrides, then
        its own ``actual`` overrides, applied.
    start_jitter : float
        Largest release delay [s]: each run the robot leaves its first dock ``start_time + U``
        later, U uniform on [0, start_jitter] (:mod:`planner.fleet.timing`).
    dwell : float
        Largest stand at each dock between two of its tasks [s]: each run and dock, uniform on
        [0, dwell].
    speed_spread : float
        Each run the robot drives at f times its planned speeds, f uniform on
        [1 - speed_spread, 1] (never faster than planned: the schedule's promises hold).
    park : str, optional
        A dock it drives to after its last task when that task's dock lies on a stretch of
        another robot's path which that robot drives after this one arrives
        (:mod:`planner.fleet.parking`); None: it waits short of that dock until the other has passed
        (where no robot could move then, the planner picks a place).
    """

    name: str
    tasks: tuple[int, ...]
    start_time: float
    robot: RobotSpec
    robot_actual: RobotSpec
    start_jitter: float = 0.0
    dwell: float = 0.0
    speed_spread: float = 0.0
    park: str | None = None


@dataclass(frozen=True)
class PlacementSpec:
    """Marker placement inputs: explicit candidate sites, or sampling along walls/obstacles."""

    candidates: tuple[tuple[float, float], ...] = ()
    spacing: float = 2.0
    cover: str = "routes"
    """``routes`` (the route network, or free-space routes between the tasks' docks) or ``free``."""
    marker_kind: MarkerKind = MarkerKind.FLAT
    """Kind of the placed markers: ``flat`` sites on faces face out of them; ``post`` everywhere."""
    existing: str = "replace"
    """``replace``: place from an empty floor (the scenario's markers are ignored); ``keep``: the
    scenario's markers stay as they are and placement adds the fewest new ones."""


@dataclass(frozen=True)
class MonteCarloSpec:
    """Monte-Carlo defaults: number of runs and the fraction that must stay under ε_max."""

    runs: int = 200
    success_target: float = 0.95
    hold: float = 0.0
    """Time each robot stands at its final dock after its last scheduled fix [s], parked, fixing
    at the sensor's rate with the schedule's last subset (a docked robot re-localising); 0: the
    episode ends there."""


@dataclass(frozen=True)
class Scenario:
    """A whole world: workspace, obstacles, markers, sensor, robot, planning and errands.

    ``sensor`` and ``robot`` are the *declared* models (planner and filter use them);
    ``sensor_actual`` and ``robot_actual`` are what the simulated hardware really does
    (equal to the declared ones unless the file has ``[sensor.actual]``/``[robot.actual]``).
    """

    name: str
    seed: int
    description: str
    workspace: Workspace
    obstacles: tuple[Obstacle, ...]
    markers: tuple[Marker, ...]
    sensor: SensorSpec
    sensor_actual: SensorSpec
    robot: RobotSpec
    robot_actual: RobotSpec
    planning: PlanningSpec
    docks: tuple[Dock, ...]
    routes: RouteNetwork | None
    tasks: tuple[Task, ...]
    montecarlo: MonteCarloSpec
    placement: PlacementSpec = field(default_factory=PlacementSpec)
    source: str = "<memory>"
    """Where the scenario came from (the path as given, or ``NAME.toml`` for a built-in), for messages."""
    text: str = ""
    """The TOML text it was loaded from (Monte-Carlo keeps it beside the results)."""
    floorplan: FloorPlan | None = None
    """The drawing or map its obstacles and markers were read from (``[floorplan]``), if any."""
    files: tuple[Path, ...] = field(default=(), compare=False)
    """Every file it was read from, absolute: the scenario TOML (when loaded from a file), the floor
    plan's files and the route graph file; ``pefsim watch`` follows them."""
    robots: tuple[FleetRobot, ...] = ()
    """The fleet (``[[robots]]``), empty for a scenario of one robot (``robot``, driving the tasks
    one episode at a time, as without a fleet)."""
    unknown: tuple[Obstacle, ...] = ()
    """Areas nobody knows (``[[unknown]]``; a ROS map's unknown cells): neither floor nor wall. The
    planner treats them as blocking (no route through them, no line of sight across them is
    counted on, no candidate site on them); the simulation has nothing there."""

    @property
    def is_fleet(self) -> bool:
        """Tell whether the scenario has ``[[robots]]`` (a fleet in one world)."""
        return bool(self.robots)

    def overview(self) -> dict:
        """Return the scenario in brief as a JSON-ready dict (each row of ``pefsim list --json``).

        ``name``, ``size`` [w, h] [m], the counts of ``markers``, ``docks`` and ``tasks``, ``description``.
        """
        return {"name": self.name, "size": list(self.workspace.size), "markers": len(self.markers),
                "docks": len(self.docks), "tasks": len(self.tasks), "description": self.description}

    def marker_heights(self) -> np.ndarray:
        """Reflector centre heights [m], shape (M,), NaN where a marker has none (above every robot)."""
        return np.array([math.nan if m.height is None else m.height for m in self.markers], dtype=float)

    def marker_positions(self) -> np.ndarray:
        """Marker positions, shape (M, 2) [m], in file order."""
        return np.array([m.position for m in self.markers], dtype=float).reshape(-1, 2)

    def marker_normals(self) -> np.ndarray:
        """Return the unit normals of flat markers, (0, 0) for posts, shape (M, 2), in file order."""
        return np.array([m.normal for m in self.markers], dtype=float).reshape(-1, 2)

    def marker_ids(self) -> list[str]:
        return [m.id for m in self.markers]

    def dock(self, name: str) -> Dock:
        """Return the dock called ``name``; raises ``KeyError`` when there is none."""
        for d in self.docks:
            if d.name == name:
                return d
        raise KeyError(name)

    def obstacle_corners(self) -> np.ndarray:
        """Corners of all obstacles, shape (n_obstacles, 4, 2) [m]; boxes only.

        Raises ``ValueError`` when an obstacle is not a box: use :meth:`obstacle_pieces`,
        which serves every shape.
        """
        if not self.obstacles:
            return np.zeros((0, 4, 2))
        return np.stack([o.corners() for o in self.obstacles])

    @cached_property
    def _obstacle_pieces(self) -> ConvexPieces:
        return pack_pieces(self.obstacles + self.unknown)

    def obstacle_pieces(self) -> ConvexPieces:
        """Convex pieces of all obstacles, padded for kernels (:class:`~scenarios.obstacles.ConvexPieces`).

        The unknown areas' pieces follow the obstacles' (owners ``len(obstacles)`` on): what the
        planner must not drive through nor count on seeing across. Computed once per scenario
        object (the same object every call; do not modify it).
        """
        return self._obstacle_pieces
