"""The laser marker sensor: visibility by ray tests against the physics world, noisy ranges.

The laser sits at the robot centre (the axle midpoint) at ``PhysicsConfig.laser_height``,
above the robot and below the top of the marker posts. A marker is visible when it is within
``max_range`` and the first thing a ray from the laser to the marker's axis hits is its own
post (or nothing): walls, obstacles and other markers' posts block it. A marker on a wall or
obstacle face is therefore seen from the open side, where half its post stands out.
Bullet's ray cast meets a body up to :data:`planner.pef.sight.CONTACT_REACH` before its surface
(its convex collision margin): a ray that passes that close to a wall before it enters the
marker's post stops on the wall. This is the physical half of the one line-of-sight rule of
:mod:`planner.pef.sight`: the ray ends at the point the planner's segment ends at, a hit on the
marker's own post counts as seen, and the plan counts only on lines of sight that clear
everything else by more than the reach, with the robot anywhere within its margin.

A flat marker (``normals[i]`` not zero) is seen only within ``spec.max_incidence`` of its
normal, the planner's test (:func:`planner.pef.visibility.facing_ok`, repeated here in plain
floats). Markers in :attr:`LaserSensor.blocked` are not seen at all: the episode puts there the
markers whose line of sight a passer-by blocks during a fix (``sensor.block_probability``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenarios.errors import SimulationError
from scenarios.schema import NoiseModel, SensorSpec
from sim.physics.quiet import pb
from sim.physics.world import PhysicsWorld, robot_group, robots_group


@dataclass(frozen=True)
class Measurement:
    """One marker measurement.

    Attributes
    ----------
    marker : int
        Index of the marker (row of the sensor's marker array).
    time : float
        Simulated time of the measurement [s].
    true_range : float
        Horizontal distance from the robot centre to the marker [m].
    measured_range : float
        ``true_range`` plus noise [m].
    range_bound : float
        ρ = Re·r + ρ0 at the true range [m]: the bound of uniform noise, 3σ of gaussian noise.
    true_bearing : float
        Direction of the marker in the robot frame, in (-π, π] [rad].
    measured_bearing : float or None
        ``true_bearing`` plus noise, wrapped to (-π, π] [rad]; None when the sensor measures
        ranges only.
    bearing_bound : float
        ξ [rad] (0 when ranges only).
    true_pose : ndarray, shape (3,)
        True robot pose at the measurement (x [m], y [m], theta [rad]).
    """

    marker: int
    time: float
    true_range: float
    measured_range: float
    range_bound: float
    true_bearing: float
    measured_bearing: float | None
    bearing_bound: float
    true_pose: np.ndarray


def wrap_angle(a: float) -> float:
    """Wrap an angle [rad] to (-π, π]."""
    w = math.remainder(a, 2.0 * math.pi)
    return math.pi if w == -math.pi else w


def _draw(rng: np.random.Generator, noise: NoiseModel, bound: float) -> float:
    if bound == 0.0:
        return 0.0
    # numpy's own formulas (low + (high - low) u, loc + scale z: the same numbers) on its plain
    # draws, whose calls cost a third of uniform()'s argument handling
    if noise is NoiseModel.UNIFORM:
        return -bound + (bound - -bound) * rng.random()
    return 0.0 + (bound / 3.0) * rng.standard_normal()


class LaserSensor:
    """Range (and bearing) measurements of markers in a :class:`PhysicsWorld`.

    Parameters
    ----------
    world : PhysicsWorld
        The world whose ray tests decide visibility.
    spec : SensorSpec
        The *actual* sensor (``scenario.sensor_actual``): noise, bounds, max range.
    markers : (M, 2) array_like
        Marker positions [m]. A marker standing where the world has a post is seen when the
        ray hits that post; markers without a post are seen when nothing blocks the ray.
    normals : (M, 2) array_like, optional
        Unit normals of flat markers, (0, 0) for posts (``Scenario.marker_normals``); default
        all posts.
    robot : int
        Which of the world's robots carries the laser (a fleet world's index; 0 otherwise).

    In a fleet world (``world.fleet``) the laser sits on top of its robot (``RobotSpec.height``)
    and each ray ends at its reflector's height (``Marker.height``; level with the laser for a
    reflector above every robot). The ray looks through its own robot's body; another robot's
    body blocks it (:attr:`blocked_by`), except on the way to a reflector above every robot,
    whose rays look through all robots.
    """

    def __init__(self, world: PhysicsWorld, spec: SensorSpec, markers: np.ndarray,
                 normals: np.ndarray | None = None, robot: int = 0) -> None:
        self.world = world
        self.robot = world.robots[robot]
        self.index = robot
        #: Marker -> the index of the robot whose body blocked its last ray (fleet worlds).
        self.blocked_by: dict[int, int] = {}
        self.spec = spec
        self.markers = np.asarray(markers, dtype=float).reshape(-1, 2)
        self.normals = (np.zeros_like(self.markers) if normals is None
                        else np.asarray(normals, dtype=float).reshape(-1, 2))
        self._normals = [tuple(map(float, n)) for n in self.normals]
        self._xy = [tuple(map(float, m)) for m in self.markers]
        self._cos2 = math.cos(spec.max_incidence) ** 2
        #: Markers whose line of sight is blocked now (set by the episode for each fix).
        self.blocked: frozenset[int] = frozenset()
        posts = world.scenario.marker_positions()
        # Which post (body id) belongs to each marker, matched by position; -2 never matches
        # a pybullet body id (-1 means "no hit").
        self._own_post = np.full(len(self.markers), -2, dtype=int)
        for i, m in enumerate(self.markers):
            if len(posts):
                j = int(np.argmin(np.hypot(*(posts - m).T)))
                if math.hypot(*(posts[j] - m)) < 1e-9:
                    self._own_post[i] = world.post_ids[j]
        h = self.robot.spec.height if world.fleet else world.config.laser_height
        self.height = h
        # Ray ends in the physics world's local coordinates (user's frame - workspace origin).
        self._x0, self._y0 = (float(v) for v in world.origin)
        heights = [None] * len(self.markers)
        if world.fleet:
            heights = [world.scenario.markers[i].height if i < len(world.scenario.markers) else None
                       for i in range(len(self.markers))]
        self._targets = [[float(x) - self._x0, float(y) - self._y0, h if z is None else float(z)]
                         for (x, y), z in zip(self.markers, heights, strict=True)]
        # Collision masks of the rays (fleet worlds): through its own body, or through every robot's.
        self._bodies = {b: j for j, b in enumerate(world.body_ids)}
        own, every = robot_group(robot), robots_group(len(world.body_ids))
        self._masks = [-1 ^ (every if z is None else own) for z in heights] if world.fleet else None

    def origin(self) -> np.ndarray:
        """Laser position (x, y, z) [m], shape (3,): the robot centre at the laser height (user's frame)."""
        x, y, _ = self.robot.true_pose()
        return np.array([x, y, self.height])

    def _check_index(self, i: int) -> None:
        if not 0 <= i < len(self.markers):
            raise SimulationError(f"laser: marker index {i} out of range (0..{len(self.markers) - 1})")

    def visible(self, i: int) -> bool:
        """Tell whether marker ``i`` is within max range and its line of sight is clear."""
        self._check_index(i)
        return self._visible_from(i, self.robot.true_pose())

    def _facing(self, i: int, x: float, y: float) -> bool:
        """Tell whether local point (x, y) [m] is in marker i's incidence wedge (always, for a post)."""
        nx, ny = self._normals[i]
        if nx == 0.0 and ny == 0.0:
            return True
        tx, ty, _ = self._targets[i]
        dx, dy = x - tx, y - ty
        dot = dx * nx + dy * ny
        return dot >= 0.0 and dot * dot >= (dx * dx + dy * dy) * self._cos2

    def _visible_from(self, i: int, pose: np.ndarray) -> bool:
        x, y = float(pose[0]) - self._x0, float(pose[1]) - self._y0
        tx, ty, h = self._targets[i]
        if i in self.blocked or math.hypot(tx - x, ty - y) > self.spec.max_range or not self._facing(i, x, y):
            return False
        if self._masks is None:
            hit = pb.rayTest([x, y, h], self._targets[i], physicsClientId=self.world.client)[0]
            return bool(hit[0] == -1 or hit[0] == self._own_post[i])
        hit = pb.rayTest([x, y, self.height], self._targets[i], collisionFilterMask=self._masks[i],
                         physicsClientId=self.world.client)[0]
        other = self._bodies.get(hit[0])
        if other is not None:
            self.blocked_by[i] = other
            return False
        self.blocked_by.pop(i, None)
        return bool(hit[0] == -1 or hit[0] == self._own_post[i])

    def hidden_by_robots(self) -> dict[int, int]:
        """Every line of sight another robot's body hides now: marker index -> that robot's index.

        A marker counts when the laser would see it without the robots (within max range, in its
        incidence wedge, not blocked for the fix (:attr:`blocked`), no wall or post on the way) and
        another robot's body is on its ray. Reflectors above every robot are never hidden. Empty
        outside a fleet world.

        Returns
        -------
        dict of int to int
            Marker index -> index of the first robot body on its ray.
        """
        if self._masks is None:
            return {}
        x0, y0, _ = self.robot.true_pose_tuple()
        x, y = float(x0) - self._x0, float(y0) - self._y0
        start = [x, y, self.height]
        bare = -1 ^ robots_group(len(self.world.body_ids))  # the same ray through every robot
        out = {}
        for i, target in enumerate(self._targets):
            if i in self.blocked or math.hypot(target[0] - x, target[1] - y) > self.spec.max_range \
                    or not self._facing(i, x, y):
                continue
            hit = pb.rayTest(start, target, collisionFilterMask=self._masks[i], physicsClientId=self.world.client)[0]
            other = self._bodies.get(hit[0])
            if other is None:
                continue
            clear = pb.rayTest(start, target, collisionFilterMask=bare, physicsClientId=self.world.client)[0][0]
            if clear == -1 or clear == self._own_post[i]:
                out[i] = other
        return out

    def sees_all(self, indices) -> bool:
        """Tell whether every marker of ``indices`` is visible now (stops at the first that is not).

        The check of a fix's scheduled markers, once per fix: plain floats and a ray each. Right
        after physics steps the interpreter runs from cold caches, and the numpy calls of
        :meth:`visible_all` cost ~150 us there (a fifth of an episode's laser time).
        """
        pose = self.robot.true_pose_tuple()
        for i in indices:
            self._check_index(int(i))
            if not self._visible_from(int(i), pose):
                return False
        return True

    def visible_all(self, indices=None) -> np.ndarray:
        """Visibility of every marker, or of the markers ``indices``: shape (M,) or (len(indices),) bool.

        One batched ray test.
        """
        idx = np.arange(len(self.markers)) if indices is None else np.asarray(indices, dtype=int).reshape(-1)
        if idx.size == 0:
            return np.zeros(0, dtype=bool)
        if idx.size <= 3 or self._masks is not None:
            # A ray costs ~5 us; a batch call and its numpy bookkeeping ~20 us more. (A fleet's
            # rays have a mask each, which a batch cannot take.)
            pose = self.robot.true_pose()
            return np.array([self._visible_from(int(i), pose) for i in idx])
        origin = self.origin()
        in_range = np.hypot(*(self.markers[idx] - origin[:2]).T) <= self.spec.max_range
        local = [float(origin[0]) - self._x0, float(origin[1]) - self._y0, float(origin[2])]
        hits = pb.rayTestBatch([local] * idx.size, [self._targets[i] for i in idx],
                               physicsClientId=self.world.client)
        body = np.array([h[0] for h in hits], dtype=int)
        x, y = local[0], local[1]
        ok = np.array([int(i) not in self.blocked and self._facing(int(i), x, y) for i in idx], dtype=bool)
        return in_range & ok & ((body == -1) | (body == self._own_post[idx]))

    def measure(self, i: int, rng: np.random.Generator, pose: tuple[float, float, float] | None = None) -> Measurement:
        """Measure marker ``i`` now, drawing noise from ``rng``.

        ``pose`` is the robot's true pose now (x, y, theta) if the caller has read it already
        (:meth:`sim.physics.robot.DiffDriveRobot.true_pose_tuple`); it is read otherwise.

        Range noise: uniform in ±ρ or gaussian with σ = ρ/3, ρ = Re·r + ρ0 at the true range.
        Bearing (when the spec's bearing error ξ > 0): likewise with ξ. The range is drawn
        first, then the bearing.

        Raises
        ------
        SimulationError
            If marker ``i`` is not visible (callers check :meth:`visible` first).
        """
        self._check_index(i)
        # plain floats: called between physics steps, where numpy's calls run from cold caches
        px, py, pth = (float(v) for v in (self.robot.true_pose_tuple() if pose is None else pose))
        if not self._visible_from(i, (px, py)):
            raise SimulationError(f"laser: marker {i} at {self.markers[i].tolist()} is not visible "
                                  f"from {[round(px, 3), round(py, 3)]}")
        mx, my = self._xy[i]
        dx, dy = mx - px, my - py
        r = math.hypot(dx, dy)
        rho = float(self.spec.range_bound(r))
        measured = r + _draw(rng, self.spec.noise, rho)
        bearing = wrap_angle(math.atan2(dy, dx) - pth)
        xi = self.spec.bearing_error
        measured_bearing = (wrap_angle(bearing + _draw(rng, self.spec.noise, xi))
                            if self.spec.uses_bearing else None)
        return Measurement(marker=i, time=self.world.time, true_range=r, measured_range=measured,
                           range_bound=rho, true_bearing=bearing, measured_bearing=measured_bearing,
                           bearing_bound=xi if self.spec.uses_bearing else 0.0, true_pose=np.array([px, py, pth]))
