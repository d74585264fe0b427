"""The declared robot.radius must contain the simulated body."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import pytest

import scenarios
from scenarios.body import body_reach
from scenarios.errors import ScenarioError
from scenarios.schema import RobotSpec
from sim.physics.config import PhysicsConfig
from sim.physics.robot import urdf_text

WORLD = """
name = "body"
[workspace]
size = [10.0, 10.0]
[[markers]]
id = "M1"
position = [0.0, 0.0]
[[markers]]
id = "M2"
position = [10.0, 0.0]
[sensor]
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [2.0, 2.0, 0.0]
[[docks]]
name = "B"
pose = [8.0, 8.0, 0.0]
[[tasks]]
from = "A"
to = "B"
"""


def urdf_reach(spec: RobotSpec) -> float:
    """Farthest point of the URDF's collision shapes from the base frame, seen from above [m].

    An independent reading of what pybullet collides with: the chassis box, and the spheres of
    the wheels and casters at their joints' origins.
    """
    root = ET.fromstring(urdf_text(spec, PhysicsConfig()))
    origin = {j.find("child").get("link"): [float(v) for v in j.find("origin").get("xyz").split()]
              for j in root.iter("joint")}
    reach = 0.0
    for link in root.iter("link"):
        geo = link.find("collision/geometry")
        x, y, _ = origin.get(link.get("name"), (0.0, 0.0, 0.0))
        if geo.find("box") is not None:
            lx, ly, _ = (float(v) for v in geo.find("box").get("size").split())
            reach = max(reach, math.hypot(abs(x) + lx / 2, abs(y) + ly / 2))
        else:
            reach = max(reach, math.hypot(x, y) + float(geo.find("sphere").get("radius")))
    return reach


@pytest.mark.parametrize("spec", [
    RobotSpec(),                                                         # wheels reach farthest
    RobotSpec(wheel_radius=0.033, wheel_base=0.3, radius=0.2),           # the chassis' corners
    RobotSpec(wheel_radius=0.05, wheel_base=0.3, radius=0.201, wheel_radius_error=0.001),
    RobotSpec(wheel_radius=0.12, wheel_base=0.2, radius=0.3),            # casters force a long chassis
])
def test_reach_is_the_urdf_collision_body(spec):
    """body_reach covers the URDF's collision shapes, and is one of them.

    A wheel's cylinder, which only the inertia uses, is the only part body_reach adds; otherwise
    they are equal within float rounding.
    """
    urdf = urdf_reach(spec)
    reach = body_reach(spec)
    assert reach.distance >= urdf - 1e-12
    if "contact spheres" in reach.part or "chassis" in reach.part or "casters" in reach.part:
        assert reach.distance == pytest.approx(urdf, abs=1e-12)


def test_radius_smaller_than_the_wheels_is_refused():
    with pytest.raises(ScenarioError, match=r"^body\.toml: robot\.radius: 0\.2 is smaller than the robot's body, "
                                            r"whose wheels reach 0\.3502 m from its centre \(wheel_base/2 \+ "
                                            r"wheel radius"):
        scenarios.loads(WORLD + "[robot]\nradius = 0.2\n", source="body.toml")


def test_a_body_inside_the_radius_loads():
    sc = scenarios.loads(WORLD + "[robot]\nradius = 0.2\nwheel_base = 0.3\nwheel_radius = 0.033\n")
    assert body_reach(sc.robot_actual).distance <= sc.robot.radius


def test_actual_robot_wider_than_the_declared_radius_is_refused():
    """The simulated robot ([robot.actual]) must fit in the radius the plan keeps clear."""
    with pytest.raises(ScenarioError, match=r"robot\.radius: 0\.4 is smaller than the simulated robot's body, "
                                            r"whose wheels reach 0\.4002 m"):
        scenarios.loads(WORLD + "[robot]\nradius = 0.4\n[robot.actual]\nwheel_base = 0.6\n")


def test_fleet_override_is_checked():
    fleet = "[robot]\nradius = 0.4\n[[robots]]\nname = \"r1\"\ntasks = [0]\nradius = 0.25\n"
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.radius: 0\.25 is smaller than the robot's body"):
        scenarios.loads(WORLD + fleet)


def test_a_wheel_base_too_narrow_for_a_chassis_is_refused_at_load():
    with pytest.raises(ScenarioError, match=r"robot\.wheel_base: expected more than wheel width \+ gaps \(0\.05 m\), "
                                            r"got 0\.04$"):
        scenarios.loads(WORLD + "[robot]\nradius = 0.2\nwheel_base = 0.04\nwheel_radius = 0.03\n")
