"""What a world is: the scenario schema, TOML loading and validation, the built-in library.

The bottom package of pefsim: it imports nothing from ``estimators``, ``planner`` or ``sim``.
It also holds what every layer checks input and output against: the error types (``errors``),
the budgets (``limits``), output names (``output_names``) and JSON numbers (``jsonable``).
"""

from scenarios.errors import (
    OutputError,
    PefsimError,
    PlanningError,
    ScenarioError,
    SimulationError,
)
from scenarios.load import builtin_names, from_dict, load, loads, resolve
from scenarios.obstacles import ConvexPieces
from scenarios.route_network import RouteEdge, RouteNetwork
from scenarios.schema import (
    Dock,
    FleetRobot,
    Marker,
    MarkerKind,
    MonteCarloSpec,
    NoiseModel,
    Obstacle,
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

__all__ = [
    "ConvexPieces", "Dock", "FleetRobot", "Marker", "MarkerKind", "MonteCarloSpec", "NoiseModel", "Obstacle",
    "OutputError",
    "PefModel",
    "PefsimError", "PlacementSpec", "PlanningError", "PlanningSpec", "RobotSpec", "RouteEdge", "RouteNetwork",
    "Scenario", "ScenarioError", "SensorSpec", "SimulationError", "Task", "Weights", "Workspace",
    "builtin_names", "from_dict", "load", "loads", "resolve",
]
