"""The PyBullet world of one scenario: floor, border walls, obstacles, marker posts, robot.

Border walls only where ``workspace.walls`` (a ROS map's edge is none); a scenario's unknown
areas are no body at all (what is there is unknown: the planner does not count on it).

The world is built in *local* coordinates: the user's frame minus ``workspace.origin``, so
that a floor whose corner sits at (250000, 80000) runs with small numbers (this pybullet
build computes in double precision, where it hardly matters; a single-precision Bullet would
round positions there to about a centimetre). Poses cross that boundary only in :class:`DiffDriveRobot`
(``reset`` and ``true_pose``) and in the laser's ray ends; everything outside ``sim.physics``
sees the user's frame.

Obstacles: a box is a Bullet box, a circle a cylinder, a polygon one extruded convex mesh per
convex piece (Bullet takes the convex hull of the given vertices), so that ray tests see the
shapes the planner plans with.

One :class:`PhysicsWorld` owns one pybullet DIRECT client and passes its id on every call,
so several worlds coexist in a process. Worlds are reset, not rebuilt, between runs: the
state saved right after building is restored, which also drops Bullet's contact caches, so a
reset world drives bit-identically to a fresh one.
"""

from __future__ import annotations

import math

import numpy as np

from scenarios.errors import SimulationError
from scenarios.schema import Obstacle, Scenario
from sim.physics.config import PhysicsConfig
from sim.physics.quiet import pb, silenced
from sim.physics.robot import DiffDriveRobot

#: Lowest collision-group bit of the robots' bodies (Bullet's own filters use the low bits).
_FIRST_ROBOT_BIT = 4


def robot_group(i: int) -> int:
    """Return the collision group of robot i's body: one bit of its own."""
    return 1 << (_FIRST_ROBOT_BIT + i)


def robots_group(n: int) -> int:
    """Return the collision groups of n robots' bodies together."""
    return ((1 << n) - 1) << _FIRST_ROBOT_BIT


class PhysicsWorld:
    """A built scenario in its own pybullet client.

    Parameters
    ----------
    scenario : Scenario
        The world; the robot is built from ``scenario.robot_actual``.
    config : PhysicsConfig, optional
        Physics settings (time step, solver, geometry constants).
    pose : (3,) or (R, 3) array_like, optional
        Initial robot pose (x [m], y [m], theta [rad]); default the first dock's pose, or the
        workspace centre when there are no docks. With ``fleet``, one pose per robot of
        ``scenario.robots``; default each robot's first dock (the start of its first task).
    fleet : bool
        Build every robot of ``scenario.robots`` (each from its ``robot_actual``), each with a
        *body*: a cylinder of its radius and height that the other robots' laser rays hit (and
        nothing else: it takes no part in the dynamics). ``robot`` is then the first of them.

    Attributes
    ----------
    client : int
        The pybullet physics client id.
    robot : DiffDriveRobot
        The robot.
    post_ids : ndarray of int, shape (M,)
        pybullet body id of each marker's post, in marker order.
    blocker_ids : ndarray of int
        Body ids of the border walls (when ``workspace.walls``) and obstacles (several per
        polygon obstacle: its pieces).
    robots : list of DiffDriveRobot
        Every robot ([robot] without ``fleet``).
    body_ids : list of int
        With ``fleet``: each robot's body (the cylinder the others' rays hit); empty otherwise.
    origin : ndarray, shape (2,)
        The workspace origin [m]: local (physics) coordinates = user's frame - origin.
    body_labels : dict of int to str
        What each body is (border wall, obstacle j, marker post, robot), for messages.
    """

    def __init__(self, scenario: Scenario, config: PhysicsConfig | None = None,
                 pose: tuple[float, float, float] | np.ndarray | None = None, fleet: bool = False) -> None:
        self.scenario = scenario
        self.fleet = fleet
        if fleet and not scenario.robots:
            raise SimulationError(f"{scenario.source}: robots: a fleet world needs [[robots]]")
        self.config = config if config is not None else PhysicsConfig()
        self.origin = np.asarray(scenario.workspace.origin, dtype=float)
        self.client = -1
        with silenced():
            self.client = pb.connect(pb.DIRECT)
        if self.client < 0:
            raise SimulationError(f"pybullet: could not connect a DIRECT client (got {self.client})")
        try:
            self._build()
            if fleet:
                # every robot is loaded at the local origin: each needs its own place before a step
                if pose is None:
                    pose = [scenario.dock(scenario.tasks[r.tasks[0]].start).pose for r in scenario.robots]
                self.reset_fleet(pose)
            else:
                if pose is None:
                    x0, y0, x1, y1 = scenario.workspace.bounds
                    pose = scenario.docks[0].pose if scenario.docks else (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0)
                self.reset(pose)
        except BaseException:
            # a bad pose must not leave a physics client behind
            self.close()
            raise

    # -- building -------------------------------------------------------------------------

    def _build(self) -> None:
        cfg, cid, sc = self.config, self.client, self.scenario
        pb.setGravity(0.0, 0.0, -cfg.gravity, physicsClientId=cid)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=cfg.time_step, numSolverIterations=cfg.solver_iterations,
            numSubSteps=0, deterministicOverlappingPairs=1, physicsClientId=cid)

        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
        self.floor_id = pb.createMultiBody(0.0, plane, physicsClientId=cid)
        pb.changeDynamics(self.floor_id, -1, lateralFriction=cfg.floor_friction, physicsClientId=cid)

        w, h, t = sc.workspace.width, sc.workspace.height, cfg.wall_thickness
        # Walls lie outside the workspace rectangle; the left/right ones span the corners.
        walls = [((w / 2, -t / 2), (w + 2 * t, t)), ((w / 2, h + t / 2), (w + 2 * t, t)),
                 ((-t / 2, h / 2), (t, h)), ((w + t / 2, h / 2), (t, h))]
        # A map's border is no wall (its edge is not; only its occupied cells are): no body there.
        blockers = [self._box(c, s, 0.0, cfg.wall_height) for c, s in walls] if sc.workspace.walls else []
        #: What each static body is, for messages about what a robot touched (sim.physics.contacts).
        self.body_labels = {b: "the border wall" for b in blockers}
        for j, ob in enumerate(sc.obstacles):
            pieces = self._obstacle(ob, cfg.wall_height)
            blockers += pieces
            cx, cy = ob.center
            self.body_labels.update({b: f"obstacle {j} ({ob.kind} at ({cx:.2f}, {cy:.2f}))" for b in pieces})
        self.blocker_ids = np.array(blockers, dtype=int)

        # Posts are capsules (a cylinder with round ends, floor to post_height): Bullet ray-casts
        # a capsule ~3x faster than a cylinder, and the laser only sees the straight part. A post
        # reaches above the lasers and the reflector mounted on it (heights of a fleet).
        specs = [r.robot_actual for r in sc.robots] if self.fleet else [sc.robot_actual]
        tallest = max([cfg.laser_height, *(r.height for r in specs),
                       *(m.height for m in sc.markers if m.height is not None)])
        post_height = max(cfg.post_height, tallest + 2.0 * cfg.post_radius + 0.1)
        post = pb.createCollisionShape(pb.GEOM_CAPSULE, radius=cfg.post_radius,
                                       height=post_height - 2.0 * cfg.post_radius, physicsClientId=cid)
        self.post_ids = np.array([
            pb.createMultiBody(0.0, post, basePosition=[mx, my, 0.5 * post_height], physicsClientId=cid)
            for mx, my in sc.marker_positions() - self.origin], dtype=int)
        self.body_labels.update({int(b): f"marker post {m}"
                                 for b, m in zip(self.post_ids, sc.marker_ids(), strict=True)})

        self.robots = [DiffDriveRobot(cid, spec, cfg, origin=self.origin) for spec in specs]
        self.robot = self.robots[0]
        names = [r.name for r in sc.robots] if self.fleet else ["the robot"]
        self.body_labels.update({r.body: f"robot {name}" for r, name in zip(self.robots, names, strict=True)})
        for r in self.robots:
            r.floor = self.floor_id   # parked, a robot lets go of it (DiffDriveRobot.park)
        for r in self.robots:
            laser_at = r.spec.height if self.fleet else cfg.laser_height
            if r.geometry.top_height >= laser_at:
                raise SimulationError(
                    f"{'robot.height' if self.fleet else 'PhysicsConfig.laser_height'}: expected above the "
                    f"robot's top ({r.geometry.top_height:.3f} m), got {laser_at}")
        self.body_ids = [self._robot_body(i) for i in range(len(self.robots))] if self.fleet else []
        self._built_state = pb.saveState(physicsClientId=cid)
        self._steps = 0

    def _robot_body(self, i: int) -> int:
        """Robot i's body for the others' rays: a static cylinder moved with the robot (:meth:`place_bodies`).

        Its collision group is its own bit (:func:`robot_group`), so that robot i's laser looks
        through it and a ray to a reflector above every robot through all of them; the dynamics
        ignore it (pair filters against every robot link: static bodies never meet each other).
        """
        cid, spec = self.client, self.robots[i].spec
        shape = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=spec.radius, height=spec.height, physicsClientId=cid)
        body = pb.createMultiBody(0.0, shape, basePosition=[0.0, 0.0, 0.5 * spec.height], physicsClientId=cid)
        pb.setCollisionFilterGroupMask(body, -1, robot_group(i), 1, physicsClientId=cid)
        for r in self.robots:
            for link in range(-1, pb.getNumJoints(r.body, physicsClientId=cid)):
                pb.setCollisionFilterPair(body, r.body, -1, link, 0, physicsClientId=cid)
        return body

    def place_bodies(self) -> None:
        """Move every robot's body (:attr:`body_ids`) to the robot's true position (fleet worlds; else nothing)."""
        if not self.body_ids:
            return
        cid = self.client
        for r, body in zip(self.robots, self.body_ids, strict=True):
            x, y, _ = r.true_pose_tuple()
            pb.resetBasePositionAndOrientation(body, [x - float(self.origin[0]), y - float(self.origin[1]),
                                                      0.5 * r.spec.height], [0.0, 0.0, 0.0, 1.0],
                                               physicsClientId=cid)

    def touching(self) -> list[tuple[int, int]]:
        """Pairs (i, j), i < j, of robots whose bodies overlap now (pybullet's closest points below 0).

        Call :meth:`place_bodies` first.
        """
        out = []
        for i in range(len(self.body_ids)):
            for j in range(i + 1, len(self.body_ids)):
                pts = pb.getClosestPoints(self.body_ids[i], self.body_ids[j], 0.0, physicsClientId=self.client)
                if any(p[8] < 0.0 for p in pts):
                    out.append((i, j))
        return out

    def _obstacle(self, ob: Obstacle, height: float) -> list[int]:
        """Build one obstacle in local coordinates; return its body ids."""
        cid = self.client
        if ob.kind == "box":
            return [self._box(np.asarray(ob.center) - self.origin, ob.size, ob.yaw, height)]
        if ob.kind == "circle":
            cx, cy = np.asarray(ob.center) - self.origin
            shape = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=ob.radius, height=height,
                                            physicsClientId=cid)
            return [pb.createMultiBody(0.0, shape, basePosition=[cx, cy, 0.5 * height], physicsClientId=cid)]
        ids = []
        for piece in ob.pieces():
            local = piece - self.origin
            centre = local.mean(axis=0)
            q = local - centre   # mesh vertices about the body's position, small numbers
            verts = [[x, y, z] for z in (-0.5 * height, 0.5 * height) for x, y in q]
            shape = pb.createCollisionShape(pb.GEOM_MESH, vertices=verts, physicsClientId=cid)
            ids.append(pb.createMultiBody(0.0, shape, basePosition=[centre[0], centre[1], 0.5 * height],
                                          physicsClientId=cid))
        return ids

    def _box(self, center, size, yaw: float, height: float) -> int:
        cid = self.client
        shape = pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=[0.5 * size[0], 0.5 * size[1], 0.5 * height], physicsClientId=cid)
        quat = [0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)]
        return pb.createMultiBody(0.0, shape, basePosition=[center[0], center[1], 0.5 * height],
                                  baseOrientation=quat, physicsClientId=cid)

    # -- running --------------------------------------------------------------------------

    def reset(self, pose: tuple[float, float, float] | np.ndarray) -> None:
        """Put the robot at ``pose`` (x [m], y [m], theta [rad]) at rest and the clock at 0.

        Restores the state saved after building (contacts included), then sets the robot's
        base pose, velocities, wheel joint states and motor targets. Nothing is rebuilt. A fleet
        world takes :meth:`reset_fleet`: its other robots need places and drives of their own.
        """
        if self.fleet:
            raise SimulationError("reset: a fleet world puts every robot at once: reset_fleet(poses)")
        pose = np.asarray(pose, dtype=float)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise SimulationError(f"reset pose: expected finite (x, y, theta), got {pose.tolist()}")
        self.robot.park(False)
        pb.restoreState(stateId=self._built_state, physicsClientId=self.client)
        self.robot.reset(pose)
        self._steps = 0

    def reset_fleet(self, poses) -> None:
        """Put robot i at ``poses[i]`` (x [m], y [m], theta [rad]) at rest, the clock at 0 (fleet worlds)."""
        poses = np.asarray(poses, dtype=float)
        if poses.shape != (len(self.robots), 3) or not np.all(np.isfinite(poses)):
            raise SimulationError(f"reset poses: expected {len(self.robots)} finite (x, y, theta), "
                                  f"got {poses.tolist()}")
        for r in self.robots:
            r.park(False)
        pb.restoreState(stateId=self._built_state, physicsClientId=self.client)
        for r, pose in zip(self.robots, poses, strict=True):
            r.reset(pose)
        self._steps = 0
        self.place_bodies()

    def step(self, n: int = 1) -> None:
        """Advance the physics by ``n`` (>= 0) time steps."""
        if n < 0:
            raise SimulationError(f"step: expected a non-negative number of steps, got {n}")
        cid = self.client
        for _ in range(n):
            pb.stepSimulation(physicsClientId=cid)
        self._steps += n
        for robot in self.robots:
            robot.elapse(n * self.config.time_step)

    @property
    def time(self) -> float:
        """Simulated time since the last reset [s]."""
        return self._steps * self.config.time_step

    @property
    def steps(self) -> int:
        """Physics steps since the last reset."""
        return self._steps

    def true_pose(self) -> np.ndarray:
        """Return the robot's true pose (x [m], y [m], theta [rad]), shape (3,)."""
        return self.robot.true_pose()

    # -- lifetime -------------------------------------------------------------------------

    def close(self) -> None:
        """Disconnect the pybullet client (idempotent)."""
        if self.client >= 0:
            pb.disconnect(physicsClientId=self.client)
            self.client = -1

    def __enter__(self) -> PhysicsWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown may have torn pybullet down
            pass
