"""The small fleets several test modules drive."""


def markers_toml(positions: dict[str, tuple[float, float]]) -> str:
    """Return the ``[[markers]]`` tables of reflectors 0.3 m high at ``positions`` (id -> (x, y) [m])."""
    return "".join(f'[[markers]]\nid = "{k}"\nposition = [{x}, {y}]\nheight = 0.3\n' for k, (x, y) in positions.items())

CROSS = """
name = "cross"
seed = 3
[workspace]
size = [12.0, 12.0]
""" + markers_toml({"SW": (0.0, 0.0), "SE": (12.0, 0.0), "NE": (12.0, 12.0), "NW": (0.0, 12.0)}) + """[sensor]
[robot]
[planning]
eps_max = 0.05
resolution = 0.2
[[docks]]
name = "A"
pose = [1.0, 6.0, 0.0]
[[docks]]
name = "B"
pose = [11.0, 6.0, 0.0]
[[docks]]
name = "C"
pose = [6.0, 1.0, 90.0]
[[docks]]
name = "D"
pose = [6.0, 11.0, 90.0]
[[tasks]]
from = "A"
to = "B"
[[tasks]]
from = "C"
to = "D"
[[robots]]
name = "east"
tasks = [0]
[[robots]]
name = "north"
tasks = [1]
"""

# A hall with a rack block in the middle: a south aisle (y = 2) and a longer north one (y = 8.5)
# between a west dock W and an east dock E, and a dock N on a spur off the north aisle.
_TRADES_FLOOR = """
seed = 11
[workspace]
size = [16.0, 10.0]
[[obstacles]]
center = [8.0, 5.25]
size = [8.0, 2.5]
""" + markers_toml({"SW": (0.0, 0.0), "S": (8.0, 0.0), "SE": (16.0, 0.0), "NE": (16.0, 10.0), "NM": (5.0, 10.0),
                "NW": (0.0, 10.0), "W": (0.0, 5.0), "E": (16.0, 5.0)}) + """[sensor]
[robot]
[planning]
eps_max = 0.05
resolution = 0.2
[[docks]]
name = "W"
node = "W"
[[docks]]
name = "E"
node = "E"
yaw_deg = 180.0
[[docks]]
name = "N"
node = "N"
yaw_deg = 90.0
[routes]
segments = [["W", "wm"], ["wm", "sw"], ["wm", "nw"], ["sw", "se"], ["se", "em"], ["em", "E"], ["nw", "n"],
            ["n", "ne"], ["ne", "em"], ["n", "N"]]
[routes.nodes]
W = [1.5, 5.0]
E = [14.5, 5.0]
N = [11.0, 9.25]
wm = [3.0, 5.0]
em = [13.0, 5.0]
sw = [3.0, 2.0]
se = [13.0, 2.0]
nw = [3.0, 8.5]
n = [11.0, 8.5]
ne = [13.0, 8.5]
"""

#: Two robots trading docks: r1 W -> E while r2 E -> W (one aisle each).
SWAP = _TRADES_FLOOR.replace("seed = 11", 'name = "swap"\nseed = 11') + """
[[tasks]]
from = "W"
to = "E"
[[tasks]]
from = "E"
to = "W"
[[robots]]
name = "r1"
tasks = [0]
[[robots]]
name = "r2"
tasks = [1]
"""

#: Three robots in a rotation: r1 W -> E, r2 E -> N, r3 N -> W (each ends where the next starts).
ROTATION = _TRADES_FLOOR.replace("seed = 11", 'name = "rotation"\nseed = 11') + """
[[tasks]]
from = "W"
to = "E"
[[tasks]]
from = "E"
to = "N"
[[tasks]]
from = "N"
to = "W"
[[robots]]
name = "r1"
tasks = [0]
[[robots]]
name = "r2"
tasks = [1]
[[robots]]
name = "r3"
tasks = [2]
"""

# One corridor (y = 2, between a wall block to the north and the workspace's south wall) from a
# west dock W to an east dock E; r1 starts at M1 on the corridor and ends at M2 on it, r0 drives
# W -> E 15 s later; a dock P at the end of a spur north of the corridor, a dock Q on the
# corridor where the spur leaves it.
_CORRIDOR = """
seed = 5
[workspace]
size = [20.0, 8.0]
[[obstacles]]
center = [7.5, 5.75]
size = [15.0, 4.5]
[[obstacles]]
center = [18.75, 5.75]
size = [2.5, 4.5]
""" + markers_toml({"SW": (0.0, 0.0), "S1": (7.0, 0.0), "S2": (13.0, 0.0), "SE": (20.0, 0.0), "N1": (4.0, 3.5),
                "N2": (11.0, 3.5), "PW": (15.0, 6.0), "PE": (17.5, 6.0), "PN": (16.25, 8.0), "W": (0.0, 2.0),
                "E": (20.0, 2.0)}) + """[sensor]
[robot]
[planning]
eps_max = 0.05
resolution = 0.2
[[docks]]
name = "W"
node = "W"
[[docks]]
name = "E"
node = "E"
[[docks]]
name = "M1"
node = "M1"
[[docks]]
name = "M2"
node = "M2"
[[docks]]
name = "Q"
node = "j"
[[docks]]
name = "P"
node = "P"
yaw_deg = 90.0
[routes]
nodes = { W = [1.0, 2.0], M1 = [6.0, 2.0], M2 = [12.0, 2.0], j = [16.25, 2.0], E = [19.0, 2.0], P = [16.25, 6.5] }
segments = [["W", "M1"], ["M1", "M2"], ["M2", "j"], ["j", "E"], ["j", "P"]]
[[tasks]]
from = "W"
to = "E"
[[tasks]]
from = "M1"
to = "M2"
[[robots]]
name = "r0"
tasks = [0]
start_time = 15.0
[[robots]]
name = "r1"
tasks = [1]
"""

#: A robot that finishes on the only corridor another drives later: r1 M1 -> M2, r0 W -> E 15 s later.
#: Waiting, no robot can move: the planner picks P (Q is nearer but on r0's path).
CORRIDOR = _CORRIDOR.replace("seed = 5", 'name = "corridor"\nseed = 5')
#: ``CORRIDOR`` with r1's parking place P named: it drives M1 -> M2, then on to P, out of r0's way.
PARKED = CORRIDOR.replace('name = "corridor"', 'name = "parked"').replace(
    'name = "r1"\ntasks = [1]', 'name = "r1"\ntasks = [1]\npark = "P"')
#: ``CORRIDOR`` without the dock P: no parking place to name or pick.
NOWHERE = CORRIDOR.replace('name = "corridor"', 'name = "nowhere"').replace(
    '[[docks]]\nname = "P"\nnode = "P"\nyaw_deg = 90.0\n', '')
