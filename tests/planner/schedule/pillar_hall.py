"""The pillar hall: a route network around one 90 deg corner, a pillar put in per test (tests' helper)."""

from __future__ import annotations

import numpy as np

import scenarios

# Posts around a 12 x 8 m hall, a route network A -> c -> B with one 90 deg corner at c; a
# pillar is put in per test.
WORLD = """
name = "pillar-hall"
seed = 3
[workspace]
size = [12.0, 8.0]
{pillar}
[[markers]]
id = "M1"
position = [0.0, 0.0]
[[markers]]
id = "M2"
position = [6.0, 0.0]
[[markers]]
id = "M3"
position = [12.0, 0.0]
[[markers]]
id = "M4"
position = [0.0, 8.0]
[[markers]]
id = "M5"
position = [6.0, 8.0]
[[markers]]
id = "M6"
position = [12.0, 8.0]
[[markers]]
id = "M7"
position = [0.0, 4.0]
[[markers]]
id = "M8"
position = [12.0, 4.0]
[sensor]
relative_error = 1e-4
absolute_error = 0.001
noise = "uniform"
max_range = 20.0
[robot]
radius = 0.4
max_speed = 1.0
max_yaw_rate = 0.5      # arcs of 2 m at cruising speed: the corner is an arc, not a stop
[planning]
eps_max = 0.05
[[docks]]
name = "A"
pose = [1.5, 2.0, 0.0]
[[docks]]
name = "B"
pose = [9.0, 6.5, 90.0]
[routes]
nodes = {{ A = [1.5, 2.0], c = [9.0, 2.0], B = [9.0, 6.5] }}
segments = [["A", "c"], ["c", "B"]]
"""

PILLAR = "[[obstacles]]\ncenter = [{x}, {y}]\nradius = {r}\n"


def world(x=None, y=None, r=0.3):
    return scenarios.loads(WORLD.format(pillar="" if x is None else PILLAR.format(x=x, y=y, r=r)))


def arc_middle(plan, m):
    """Return the check's sample nearest the middle of the corner's arc, and the unit vector to its centre."""
    r = 1.0 / plan.candidates[plan.chosen].path.curvature.max()
    centre = np.array([9.0 - r, 2.0 + r])           # the arc is tangent to y = 2 and x = 9
    mid = centre + r * np.array([1.0, -1.0]) / np.sqrt(2.0)
    i = int(np.argmin(np.hypot(*(m.points - mid).T)))
    return i, (centre - m.points[i]) / np.hypot(*(centre - m.points[i]))
