"""Entity paths, timeline and styling of pefsim recordings (the contract; no rerun import).

Entity paths are what other tools and users rely on to find data in a ``.rrd`` file; all
spatial data is in metres in the workspace frame (origin lower-left, x right, y up).
"""

from __future__ import annotations

from types import SimpleNamespace

APPLICATION_ID = "pefsim"
TIMELINE = "sim_time"
"""Duration timeline: simulation time since the episode started [s]."""

# --- spatial, static -------------------------------------------------------------------
WORLD = "world"
WORKSPACE = "world/workspace"
OBSTACLES = "world/obstacles"
MARKERS = "world/markers"
MARKER_FACING = "world/markers/facing"
"""Flat reflectors: the face (a short line across the normal) and the normal as an arrow."""
DOCKS = "world/docks"
PEF = "world/pef"
PEF_NO_FIX = "world/pef/no_fix"
"""Cells with τ = ∞ over the heatmap (a child of :data:`PEF`: its image transform applies)."""
REGION = "world/region"
CANDIDATES = "world/routes/candidates"
CHOSEN = "world/routes/chosen"
PATH = "world/routes/path"
SCHEDULE = "world/schedule"
NETWORK = "world/routes/network"
"""The route network's segments, coloured by their worst τ (``pefsim watch``)."""
NETWORK_OK = "world/routes/network/admissible"
NETWORK_BAD = "world/routes/network/inadmissible"
NETWORK_NO_FIX = "world/routes/network/no_fix"
"""Segments with a point of τ = ∞ (fewer than k markers in sight), drawn apart from finite τ."""
TASKS = "world/tasks"
"""A live view's plans, one subtree per task: ``world/tasks/<i>/routes/chosen``, ..."""

# --- spatial, on the timeline ------------------------------------------------------------
ROBOT_TRUE = "world/robot/true"
ROBOT_ESTIMATE = "world/robot/estimate"
TRUE_TRAIL = "world/robot/true/trail"
ESTIMATE_TRAIL = "world/robot/estimate/trail"
COVARIANCE = "world/robot/covariance"
FIX_RAYS = "world/fix/rays"
FIX_FAULT_AREA = "world/fix/fault_area"
FIX_PREDICTED = "world/fix/predicted"
FIX_SNAPSHOT = "world/fix/snapshot"
FIX_TRUE = "world/fix/true"

# --- scalars and text --------------------------------------------------------------------
METRICS = "metrics"
ERROR = "metrics/error"
PREDICTED_TAU = "metrics/predicted_tau"
EPS_MAX = "metrics/eps_max"
PEF_TAU = "metrics/pef_tau"
FAULT_DIAMETER = "metrics/fault_diameter"
FIX_PREDICTED_TAU = "metrics/fix_predicted_tau"
NEES = "metrics/nees"
NEES_UPPER = "metrics/nees_upper"
NIS = "metrics/nis"
EVENTS = "events"
SUMMARY = "summary"
PLAN_TEXT = "plan"
VIEW_TEXT = "view"
"""A live view's summary: what was read, the plans and why a task has none."""


def of_task(entity: str, task: int) -> str:
    """Return the entity of a live view's task ``task`` for a plan entity (``world/...`` or ``plan``)."""
    if entity.startswith(f"{WORLD}/"):
        return f"{TASKS}/{task}/{entity[len(WORLD) + 1:]}"
    return f"{entity}/{task}"

def of_robot(name: str) -> SimpleNamespace:
    """Return the episode entities of a fleet's robot ``name``: ``world/robots/<name>/...``, ``metrics/<name>/...``.

    Attributes are named as this module's episode entities (:data:`EPISODE_ENTITIES`), plus
    ``BLOCKED_RAYS`` (the lines of sight other robots hid at its fixes) and ``RESERVED`` (the
    zones it held).
    """
    out = {}
    for key, value in globals().items():
        if isinstance(value, str) and value in EPISODE_ENTITIES:
            if value.startswith("world/robot/"):
                out[key] = f"{ROBOTS}/{name}/{value[len('world/robot/'):]}"
            elif value.startswith(f"{WORLD}/"):
                out[key] = f"{ROBOTS}/{name}/{value[len(WORLD) + 1:]}"
            else:
                head, _, tail = value.partition("/")
                out[key] = f"{head}/{name}/{tail}" if tail else f"{head}/{name}"
    out["BLOCKED_RAYS"] = f"{ROBOTS}/{name}/fix/blocked_rays"
    out["RESERVED"] = f"{ROBOTS}/{name}/reserved"
    return SimpleNamespace(**out)


ROBOTS = "world/robots"
"""A fleet's robots, one subtree each (:func:`of_robot`)."""
BLOCKED_MAP = "world/blocked"
"""Where lines of sight were hidden by robots: the hidden rays of every robot's fixes."""

STATIC_ENTITIES = (WORKSPACE, OBSTACLES, MARKERS, DOCKS)
"""Logged by :func:`interop.recording.log_static` for every scenario."""
MAP_ENTITIES = (PEF, REGION)
"""Logged when a PEF map is given."""
PLAN_ENTITIES = (CANDIDATES, CHOSEN, PATH, SCHEDULE, PLAN_TEXT)
"""Logged when a plan is given (``CHOSEN``/``PATH`` only when the plan has them)."""
EPISODE_ENTITIES = (ROBOT_TRUE, ROBOT_ESTIMATE, TRUE_TRAIL, ESTIMATE_TRAIL, COVARIANCE,
                    FIX_RAYS, FIX_FAULT_AREA, FIX_PREDICTED, FIX_SNAPSHOT, FIX_TRUE,
                    ERROR, PREDICTED_TAU, EPS_MAX, PEF_TAU, FAULT_DIAMETER, FIX_PREDICTED_TAU,
                    NEES, NEES_UPPER, NIS, EVENTS, SUMMARY)
"""Logged by :func:`interop.recording.log_episode`."""

# --- styling: RGB, and sizes in UI points (rerun draws negative radii in screen points) ----
GREY = (150, 150, 150)
OBSTACLE = (200, 120, 60)
MARKER = (250, 220, 40)
DOCK = (90, 160, 255)
CANDIDATE_OK = (120, 120, 200)
CANDIDATE_BAD = (200, 60, 60)
CHOSEN_ROUTE = (80, 200, 255)
PATH_ROUTE = (255, 255, 255)
FIX_POINT = (255, 160, 0)
SWITCH_POINT = (255, 60, 200)
NO_FIX = (170, 60, 255)
"""τ = ∞ (no fix possible): a colour off the finite τ ramp (green - yellow - red), not its worst end."""
NO_FIX_CELL = (70, 70, 70, 255)
"""RGBA of a map cell with τ = ∞ (inside a rack, or seeing no usable subset): dark grey, off the
heatmap's colormap, whose top end is "bad but finite"; cells with a fix are transparent in that layer."""
TAU_GOOD = (40, 200, 80)
TAU_MID = (250, 210, 40)
TAU_LIMIT = (230, 40, 40)
TRUE = (60, 220, 90)
ESTIMATE = (255, 140, 40)
REGION_LINE = (255, 255, 255)
RAY = (250, 220, 40)
CONTAINED = (0, 220, 220)
NOT_CONTAINED = (255, 40, 40)
PREDICTED = (230, 230, 230)
SNAPSHOT = (220, 80, 255)
EPS_LINE = (255, 60, 60)
NIS_POINT = (120, 180, 255)

LINE_PT = 1.0
THICK_LINE_PT = 2.0
POINT_PT = 4.0
BIG_POINT_PT = 6.0
