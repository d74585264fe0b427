"""The budgets of pefsim: how large an input, and the work it asks for, may be.

Every reader and every planner stage that allocates in proportion to its input checks its
budget *before* the work, and a file or a key over it is one error line naming the file, the
key or entity, the count and the limit (README, "Limits"). Each budget says why it is where it
is: far above any real floor, far below what a machine with a few GB of memory survives.
"""

from __future__ import annotations

import re
import sys

import numpy as np

MAX_NESTING = 100
"""Deepest nesting of arrays and tables in a scenario (TOML) or a route graph (JSON): real files
nest under 10 deep; Python's parsers recurse once per level and fail near 1000."""
MAX_DXF_ENTITIES = 500_000
"""Most entities a DXF drawing may hold after block expansion (INSERT and MINSERT grids, nested
blocks): counted from the block definitions before anything is expanded; reading costs ~50 µs
per entity, so the budget is about half a minute of reading."""
MAX_MAP_PIXELS = 25_000_000
"""Most pixels of a ROS map image (5000 x 5000: a 250 m square at 5 cm): read from the image's
header before it is decoded; the shades, the mask and the traced outlines take up to ~150 bytes
per pixel, 4 GB at the budget."""
MAX_YAML_NODES = 100_000
"""Most nodes of a map YAML once its aliases are expanded: a map_server YAML has about ten;
aliases of aliases grow exponentially (the "billion laughs")."""
MAX_RING_VERTICES = 10_000
"""Most vertices of one obstacle ring: the convex pieces, line-of-sight kernels and placement
cost grow with the vertices of an obstacle (a drawing's 20 000-gon exhausts memory in place)."""
MIN_LENGTH = 1e-9
"""Shortest obstacle size, radius or polygon edge [m]: the precision scenarios are written with
(1 nm); shorter ones have squared lengths that underflow in the geometry."""
MAX_GRID_CELLS = 200_000_000
"""Largest PEF grid (workspace / planning.resolution) a scenario may ask for: 2e8 cells is
already 1.6 GB per float64 layer."""
MIN_GRID_CELLS = 2
"""Fewest grid cells along each side of the workspace: the route search interpolates between
neighbouring cells."""
MAX_PATH_SAMPLES = 10_000_000
"""Most samples of a planned path in time: the planner samples a route at least
:data:`SAMPLES_PER_FIX` times per fix interval (1 / sensor.fix_rate_hz), so the slowest speed
and yaw rate follow from it (a 1e-6 m/s robot needs 1e8 samples to cross a 10 m room)."""
SAMPLES_PER_FIX = 4
"""Fewest path samples per fix interval (the planner's time grid)."""
MAX_PEF_PASSES = 64
"""Most plain PEF evaluations per point for redundancy r: k^r (every member of the best subset
removed, recursively), so r = 6 with k = 2, r = 2 with k = 8."""
MAX_RUNS = 10**7
"""Most Monte-Carlo runs of one sweep (montecarlo.runs, mc --runs): its tables keep a row per run."""
MAX_HOLD = 3600.0
"""Longest montecarlo.hold [s]: an hour at a dock is 216,000 control steps of a run's log."""

# A TOML or JSON string (the four TOML kinds, JSON's is the basic one) or a TOML comment: their
# brackets do not nest anything.
_NOT_NESTING = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*')


def nesting_depth(text: str) -> int:
    """Deepest nesting of brackets and braces in TOML or JSON ``text``, outside strings and comments.

    A linear scan (no recursion), so it can be asked before a recursive parser sees the text.
    Unbalanced or malformed text gives an upper bound of the depth a parser would reach.
    """
    if "[" not in text and "{" not in text:
        return 0
    stripped = _NOT_NESTING.sub("", text)
    codes = np.frombuffer(stripped.encode("utf-8", "replace"), dtype=np.uint8)
    step = np.zeros(codes.shape, dtype=np.int64)
    step[(codes == ord("[")) | (codes == ord("{"))] = 1
    step[(codes == ord("]")) | (codes == ord("}"))] = -1
    return int(np.cumsum(step).max(initial=0))


def long_integer(text: str) -> str:
    """Describe the first integer of ``text`` too long for Python to convert (its line and digit count)."""
    limit = sys.get_int_max_str_digits()
    found = re.search(r"[0-9][0-9_]{%d,}" % limit, text)
    if found is None:
        return f"an integer of more than {limit} digits"
    line = text.count("\n", 0, found.start()) + 1
    digits = sum(c.isdigit() for c in found.group())
    return f"an integer of {digits} digits (at line {line}), at most {limit}"


MAX_HEIGHT = 20.0
"""Tallest robot (``robot.height``) and highest reflector (``[[markers]] height``) [m]: a hall's
roof; anything higher is a unit mistake (millimetres)."""
MAX_ROBOTS = 24
"""Most robots of a fleet (``[[robots]]``): each robot's body needs a collision-filter bit of its
own in the physics (so that its own laser looks through it), and Bullet's groups are 32-bit ints
whose low bits it uses itself; zone control checks each path against every other's."""
MAX_ROBOT_TASKS = 1000
"""Most tasks one robot of a fleet drives (``[[robots]] tasks``): each is planned on its own."""
MAX_NAME_BYTES = 255
"""Longest component of an output path [bytes of UTF-8]: NAME_MAX of ext4, XFS, Btrfs, APFS
and NTFS; a longer name fails only when the file is opened, after the work (``File name too
long``), so every output name (a default ``mc-<scenario name>`` too) is checked before it."""
MAX_PATH_BYTES = 4096
"""Longest output path [bytes of UTF-8]: Linux's PATH_MAX, for the same reason."""
MAX_WORLDS = 10_000
"""Most random worlds of one ``pefsim worlds`` (``--count``): each is drawn and planned, 1-10 s
a world, so the budget is already a day of drawing; each world is written as it is drawn."""
MAX_MARKERS = 2000
"""Most markers of a scenario (``[[markers]]`` and a drawing's reflectors together): the PEF
scores the C(M, k) subsets at every point, at most 2e6 of them, and C(2000, 2) = 1 999 000 is
the largest M that any k >= 2 allows; checked before the markers are read."""
MAX_CANDIDATES = 20_000
"""Most ``placement.candidates``: the cover problem is a sites x points matrix (up to 2000 free
points, or the route points), 4e7 entries at the budget, before the LP and the search."""
MAX_SCENARIO_BYTES = 4_000_000
"""Largest scenario file (TOML) [bytes]: Python's TOML parser reads about 0.5 MB a second, so
the budget is seconds; a hand-written scenario is kilobytes (floor plans come from drawings)."""
MAX_SPLINE_FIT_POINTS = 2000
"""Most fit points of one DXF SPLINE: ezdxf interpolates them by a dense n x n solve (32 MB and
~0.6 s at the budget; 30 000 fit points asked for 7.4 GB)."""
MAX_FIT_POINTS = 50_000
"""Most SPLINE fit points of a drawing in all (blocks expanded): at most 25 splines at the
per-spline budget, ~15 s of interpolation."""
MAX_GRAPH_NODES = 100_000
"""Most nodes of a route graph file (Nav2 GeoJSON, VDA LIF): each node is checked against the
obstacles and every edge's clearance swept, seconds per 10 000; a site's graph has hundreds."""
MAX_GRAPH_EDGES = 400_000
"""Most edges of a route graph file (four per node on average: a grid's)."""
MAX_GRAPH_BYTES = 50_000_000
"""Largest route graph file [bytes]: JSON is parsed whole (about 10 times its size in memory)."""
