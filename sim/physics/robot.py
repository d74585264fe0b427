"""The differential-drive robot: its URDF (filled from the actual RobotSpec) and its motors.

Its dimensions are :func:`scenarios.body.robot_geometry`'s, the same the loader checks the
declared radius against (:func:`scenarios.body.body_reach`).

The systematic odometry error is physical here: the right wheel's radius is
``r (1 + wheel_radius_error)`` and the left one's ``r (1 - wheel_radius_error)`` of the
*actual* spec, while the odometry converts encoder angles with the *nominal* radius.
"""

from __future__ import annotations

import functools
import math
import tempfile
from importlib import resources
from pathlib import Path
from string import Template

import numpy as np

from scenarios.body import FRONT_LOAD, robot_geometry
from scenarios.errors import SimulationError
from scenarios.schema import RobotSpec
from sim.physics.config import PhysicsConfig
from sim.physics.quiet import pb, silenced

_CASTER_MASS_FRACTION = 0.01   # casters are light plastic balls; a share of the chassis mass [-]

#: The drive's position loop [1/s]: each wheel's rate setpoint is its command plus this gain
#: times the angle the wheel is behind the command's integral. Bullet's velocity motor alone
#: leaves a wheel ~1e-4 of its rate short under load, for good (a proportional loop); a motor
#: controller's integral action does not, and the encoders' phase follows the command (and
#: the filter predicts it, ``estimators.motion_quantised``). Set at each command, every control
#: tick (1/60 s), the loop takes off half the lag a tick: fast, and stable for ticks shorter than
#: 1/15 s (gain x tick < 2). A lag clamped at FOLLOWING_LIMIT is a turn the wheel never makes up:
#: the filter's commanded sums keep it, so its encoder phase is off from then on.
DRIVE_GAIN = 30.0
#: The lag past which the loop stops integrating the command [rad]: a wheel held back by a
#: wall (or torque-limited for long) is not sent after the whole angle it missed.
FOLLOWING_LIMIT = 0.2


@functools.lru_cache(maxsize=1)
def _template() -> Template:
    return Template(resources.files("sim.physics").joinpath("diffdrive.urdf").read_text())


def urdf_text(spec: RobotSpec, config: PhysicsConfig) -> str:
    """Fill the package template ``diffdrive.urdf`` from ``spec``: the robot's URDF.

    Parameters
    ----------
    spec : RobotSpec
        The actual (simulated) robot: radii, wheel base, wheel error, mass.
    config : PhysicsConfig
        Wheel width and friction, mass fractions, caster clearance.

    Returns
    -------
    str
        URDF XML.
    """
    g = robot_geometry(spec, config.wheel_width)
    m = spec.mass
    mw = config.wheel_mass_fraction * m
    mc = _CASTER_MASS_FRACTION * m
    L, W, H = g.chassis_length, g.chassis_width, g.chassis_height
    w = config.wheel_width

    def f(x: float) -> str:
        return repr(float(x))

    def wheel_inertia(radius: float) -> tuple[str, str]:
        # Solid cylinder: about its axle (y) m r^2 / 2, about a diameter m (3 r^2 + w^2) / 12.
        return f(mw * (3 * radius ** 2 + w ** 2) / 12.0), f(0.5 * mw * radius ** 2)

    left_ixx, left_iyy = wheel_inertia(g.left_radius)
    right_ixx, right_iyy = wheel_inertia(g.right_radius)
    return _template().substitute(
        axle_height=f(g.axle_height), caster_clearance=f(config.caster_clearance),
        front_load=f"{FRONT_LOAD:.0%}", wheel_width=f(w),
        com_x=f(g.com_x), com_z=f(g.com_z), chassis_mass=f(m), chassis_z=f(0.0),
        # Box inertia about its centre (the centre of mass sits lower, an approximation that
        # only changes how the body pitches between the casters).
        chassis_ixx=f(m * (W ** 2 + H ** 2) / 12.0), chassis_iyy=f(m * (L ** 2 + H ** 2) / 12.0),
        chassis_izz=f(m * (L ** 2 + W ** 2) / 12.0),
        chassis_length=f(L), chassis_width=f(W), chassis_height=f(H),
        wheel_friction=f(config.wheel_friction), wheel_mass=f(mw),
        left_ixx=left_ixx, left_iyy=left_iyy, right_ixx=right_ixx, right_iyy=right_iyy,
        left_radius=f(g.left_radius), right_radius=f(g.right_radius),
        left_z=f(g.left_radius - g.axle_height), right_z=f(g.right_radius - g.axle_height),
        half_base=f(0.5 * spec.wheel_base), half_pi=f(0.5 * math.pi),
        caster_mass=f(mc), caster_i=f(0.4 * mc * g.caster_radius ** 2), caster_radius=f(g.caster_radius),
        caster_x=f(g.caster_x),
        front_caster_z=f(g.caster_radius - g.axle_height),
        back_caster_z=f(g.caster_radius - g.axle_height + config.caster_clearance),
    )


class DiffDriveRobot:
    """The simulated robot in one pybullet client: wheel motors, encoders, true pose.

    The motors are velocity-controlled with a position loop around them (``DRIVE_GAIN``): a
    command holds until the next one, the setpoint angles advance by it as the world steps
    (:meth:`elapse`), and each command adds the gain times the wheel's lag behind its setpoint.

    Parameters
    ----------
    client : int
        pybullet physics client id (owned by the world).
    spec : RobotSpec
        The actual robot (``scenario.robot_actual``).
    config : PhysicsConfig
        Physics settings.
    origin : (2,) array_like
        The workspace origin [m]: poses given and returned are in the user's frame, the body
        sits at ``pose - origin`` in the physics world.
    """

    def __init__(self, client: int, spec: RobotSpec, config: PhysicsConfig,
                 origin: tuple[float, float] | np.ndarray = (0.0, 0.0)) -> None:
        self.client = client
        # Poses come and go in the user's frame; the body lives at pose - origin (see world.py).
        self._x0, self._y0 = float(origin[0]), float(origin[1])
        self.spec = spec
        self.geometry = robot_geometry(spec, config.wheel_width)
        text = urdf_text(spec, config)
        with tempfile.TemporaryDirectory(prefix="pefsim-") as tmp:
            path = Path(tmp) / "diffdrive.urdf"
            path.write_text(text)
            with silenced():
                self.body = pb.loadURDF(
                    str(path), basePosition=[0.0, 0.0, self.geometry.axle_height],
                    flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
        if self.body < 0:
            raise SimulationError(f"robot URDF: pybullet could not load it (body id {self.body})")
        names = {pb.getJointInfo(self.body, j, physicsClientId=client)[1].decode(): j
                 for j in range(pb.getNumJoints(self.body, physicsClientId=client))}
        self.wheel_joints = [names["left_wheel_joint"], names["right_wheel_joint"]]
        for link in (-1, *names.values()):
            # pybullet's default link damping (0.04) is an unphysical drag on a rolling robot.
            pb.changeDynamics(self.body, link, linearDamping=0.0, angularDamping=0.0,
                              physicsClientId=client)
        # The base frame pybullet reports is the chassis' centre of mass, not the URDF link
        # frame (the axle midpoint): keep the offset to convert between them.
        # Plain floats: true_pose() runs at every control step, and numpy scalars are slow.
        self._com_local = tuple(float(v) for v in pb.getDynamicsInfo(self.body, -1, physicsClientId=client)[3])
        self._torque = [spec.max_wheel_torque, spec.max_wheel_torque]
        self._rates = [0.0, 0.0]     # the command [rad/s]
        self._setpoint = [0.0, 0.0]  # its integral since the reset [rad]
        self._pin: int | None = None  # the parking brake's constraint while parked (park)
        #: The floor's body id (set by the world): a parked robot's links stop touching it.
        self.floor: int | None = None
        self._links = [-1, *range(pb.getNumJoints(self.body, physicsClientId=client))]

    def reset(self, pose: tuple[float, float, float] | np.ndarray) -> None:
        """Put the robot level at ``pose`` (x [m], y [m], theta [rad]), at rest, motors at zero."""
        self.park(False)
        x, y, theta = (float(v) for v in pose)
        x, y = x - self._x0, y - self._y0
        c, s = math.cos(theta), math.sin(theta)
        lx, ly, lz = self._com_local
        com = [x + c * lx - s * ly, y + s * lx + c * ly, self.geometry.axle_height + lz]
        quat = [0.0, 0.0, math.sin(0.5 * theta), math.cos(0.5 * theta)]
        cid = self.client
        pb.resetBasePositionAndOrientation(self.body, com, quat, physicsClientId=cid)
        pb.resetBaseVelocity(self.body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=cid)
        for j in self.wheel_joints:
            pb.resetJointState(self.body, j, 0.0, 0.0, physicsClientId=cid)
        self._setpoint = [0.0, 0.0]
        self.set_wheel_speeds(0.0, 0.0)

    def park(self, on: bool) -> None:
        """Set the parking brake: pin the chassis where it stands (``on``) or let it go.

        Bullet's contact friction has no static phase: a robot standing on its held wheels
        slides over the floor, 10-30 µm/s and 5-15 µrad/s depending on its heading (120 s at
        rest on the warehouse floor, the wheels turning < 1 µrad), which no encoder sees; the
        filter, told by the encoders that the robot stands, grew overconfident over minutes at a
        dock (NEES 65 after 200 s). Bullet's friction anchors stop most of it, but only
        for contacts made after they are set, and they would change every drive. Parked, a fixed
        constraint holds the chassis' pose, the wheels are held at their angles and no longer touch the
        floor (whose drift would turn them under the held chassis, 0.13 mrad): the robot stands as a
        real one on its brakes does. Wheel rates other than 0 while parked raise.
        """
        cid = self.client
        if on and self._pin is None:
            pos, orn = pb.getBasePositionAndOrientation(self.body, physicsClientId=cid)
            self._pin = pb.createConstraint(self.body, -1, -1, -1, pb.JOINT_FIXED, [0.0, 0.0, 0.0],
                                            [0.0, 0.0, 0.0], pos, childFrameOrientation=orn,
                                            physicsClientId=cid)
            pb.changeConstraint(self._pin, maxForce=1e6, physicsClientId=cid)
            # the wheels held where they stand, as a brake holds them: under the velocity loop a
            # held wheel wanders by up to 0.15 mrad, and one parked at a tick edge toggled its
            # count (a tick of travel the robot never made, a jump of 0.6 mrad in heading)
            self._floor_contact(False)
            angles = list(self.wheel_angle_pair())
            self._rates = [0.0, 0.0]
            self._setpoint = angles
            pb.setJointMotorControlArray(self.body, self.wheel_joints, pb.POSITION_CONTROL, targetPositions=angles,
                                         targetVelocities=[0.0, 0.0], forces=self._torque, physicsClientId=cid)
        elif not on and self._pin is not None:
            pb.removeConstraint(self._pin, physicsClientId=cid)
            self._pin = None
            self._floor_contact(True)
            self.set_wheel_speeds(0.0, 0.0)

    def _floor_contact(self, on: bool) -> None:
        if self.floor is not None:
            for link in self._links:
                pb.setCollisionFilterPair(self.body, self.floor, link, -1, int(on), physicsClientId=self.client)

    @property
    def parked(self) -> bool:
        """Whether the parking brake holds the chassis (:meth:`park`)."""
        return self._pin is not None

    def elapse(self, seconds: float) -> None:
        """Advance the setpoint angles by ``seconds`` [s] of the command (the world's step calls it)."""
        self._setpoint[0] += self._rates[0] * seconds
        self._setpoint[1] += self._rates[1] * seconds

    def set_wheel_speeds(self, left: float, right: float) -> None:
        """Command wheel rates ``left``, ``right`` [rad/s] (velocity control, torque-limited).

        A positive rate drives the robot forward. The command holds until the next call; the
        motors are set to it plus ``DRIVE_GAIN`` times each wheel's lag behind the command's
        integral (at most ``FOLLOWING_LIMIT``).
        """
        if self._pin is not None:
            if left != 0.0 or right != 0.0:
                raise SimulationError(f"robot: wheel rates ({left:g}, {right:g}) rad/s commanded while parked")
            return
        angles = self.wheel_angle_pair()
        rates = (float(left), float(right))
        setpoints = []
        for w in range(2):
            lag = self._setpoint[w] - angles[w]
            if abs(lag) > FOLLOWING_LIMIT:
                lag = math.copysign(FOLLOWING_LIMIT, lag)
                self._setpoint[w] = angles[w] + lag
            setpoints.append(rates[w] + DRIVE_GAIN * lag)
        self._rates = list(rates)
        pb.setJointMotorControlArray(
            self.body, self.wheel_joints, pb.VELOCITY_CONTROL,
            targetVelocities=setpoints, forces=self._torque, physicsClientId=self.client)

    @property
    def following_error(self) -> tuple[float, float]:
        """Each wheel's angle minus its setpoint (left, right) [rad]: the drive's lag, negative."""
        left, right = self.wheel_angle_pair()
        return left - self._setpoint[0], right - self._setpoint[1]

    def wheel_angles(self) -> np.ndarray:
        """Unwrapped wheel joint angles (left, right), shape (2,) [rad]."""
        return np.array(self.wheel_angle_pair())

    def wheel_angle_pair(self) -> tuple[float, float]:
        """Unwrapped wheel joint angles (left, right) [rad] as floats (the control loop's read)."""
        left, right = pb.getJointStates(self.body, self.wheel_joints, physicsClientId=self.client)
        return left[0], right[0]

    def wheel_rates(self) -> np.ndarray:
        """Wheel joint rates (left, right), shape (2,) [rad/s]."""
        states = pb.getJointStates(self.body, self.wheel_joints, physicsClientId=self.client)
        return np.array([states[0][1], states[1][1]])

    def true_pose(self) -> np.ndarray:
        """Return the true pose of the axle midpoint: (x [m], y [m], theta [rad]), shape (3,)."""
        return np.array(self.true_pose_tuple())

    def true_pose_tuple(self) -> tuple[float, float, float]:
        """Return :meth:`true_pose` as floats (the control loop's read, without an array)."""
        (px, py, pz), (qx, qy, qz, qw) = pb.getBasePositionAndOrientation(
            self.body, physicsClientId=self.client)
        # Rotate the centre-of-mass offset by the base orientation and subtract it.
        lx, ly, lz = self._com_local
        r00 = 1 - 2 * (qy * qy + qz * qz)
        r01 = 2 * (qx * qy - qz * qw)
        r02 = 2 * (qx * qz + qy * qw)
        r10 = 2 * (qx * qy + qz * qw)
        r11 = 1 - 2 * (qx * qx + qz * qz)
        r12 = 2 * (qy * qz - qx * qw)
        x = px - (r00 * lx + r01 * ly + r02 * lz) + self._x0
        y = py - (r10 * lx + r11 * ly + r12 * lz) + self._y0
        return x, y, math.atan2(r10, r00)

    def tilt(self) -> float:
        """Angle between the chassis' up axis and the vertical [rad] (0 when level)."""
        _, (qx, qy, _qz, _qw) = pb.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        r22 = 1 - 2 * (qx * qx + qy * qy)
        return math.acos(max(-1.0, min(1.0, r22)))
