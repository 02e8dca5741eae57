"""The paper's grid world: placement and motion models, observations, batched episodes."""

from .actions import DELTAS, MOVING_ACTIONS, NAMES, OPPOSITE, STATIC_ACTIONS, Action, valid_mask
from .batch import BatchGridWorld
from .config import DISTRIBUTIONS, MAP_VARIANTS, MOTIONS, ConfigError, GridConfig
from .coords import DEFAULT_CELL_M, cell_to_ned, nearest_cell, ned_to_cell
from .env import GridSearchEnv
from .episodes import Episodes, sample_episodes, world_rng
from .observations import target_occupancy, views
from .placement import fixed_layout, lattice_offsets, place

__all__ = [
    "DELTAS", "MOVING_ACTIONS", "NAMES", "OPPOSITE", "STATIC_ACTIONS", "Action", "valid_mask",
    "BatchGridWorld", "DISTRIBUTIONS", "MAP_VARIANTS", "MOTIONS", "ConfigError", "GridConfig",
    "DEFAULT_CELL_M", "cell_to_ned", "ned_to_cell", "nearest_cell", "GridSearchEnv", "Episodes",
    "sample_episodes", "world_rng", "target_occupancy", "views", "fixed_layout",
    "lattice_offsets", "place",
]
