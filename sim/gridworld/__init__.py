"""The paper's grid world: placement and motion models, observations, batched episodes."""

from .actions import (
    DELTAS,
    LEVEL_ACTIONS,
    LEVEL_DELTAS,
    MOVING_ACTIONS,
    NAMES,
    OPPOSITE,
    STATIC_ACTIONS,
    Action,
    valid_mask,
)
from .batch import BatchGridWorld
from .config import DISTRIBUTIONS, MAP_VARIANTS, MOTIONS, ConfigError, GridConfig
from .coords import DEFAULT_CELL_M, GridFrame, cell_to_ned, nearest_cell, ned_to_cell
from .detection import (
    FLIGHT,
    DetectionTable,
    FlightModel,
    default_table,
    level_height_m,
    view_radius,
)
from .env import GridSearchEnv
from .episodes import Episodes, detection_rng, sample_episodes, world_rng
from .observations import target_occupancy, views
from .placement import fixed_layout, lattice_offsets, place

__all__ = [
    "DELTAS", "MOVING_ACTIONS", "NAMES", "OPPOSITE", "STATIC_ACTIONS", "Action", "valid_mask",
    "BatchGridWorld", "DISTRIBUTIONS", "MAP_VARIANTS", "MOTIONS", "ConfigError", "GridConfig",
    "DEFAULT_CELL_M", "GridFrame", "cell_to_ned", "ned_to_cell", "nearest_cell", "GridSearchEnv", "Episodes",
    "sample_episodes", "world_rng", "target_occupancy", "views", "fixed_layout",
    "lattice_offsets", "place", "LEVEL_ACTIONS", "LEVEL_DELTAS", "FLIGHT", "DetectionTable", "FlightModel",
    "default_table", "level_height_m", "view_radius", "detection_rng",
]
