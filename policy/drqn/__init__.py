"""The DRQN baseline (paper Section V-D 2)."""

from .agent import DrqnPolicy
from .model import Drqn, drqn_view
from .train import (
           DrqnConfig,
           DrqnLearner,
           EpisodeReplay,
           load_drqn,
           save_drqn,
           td_targets,
           train_drqn,
)

__all__ = ["Drqn", "DrqnConfig", "DrqnLearner", "DrqnPolicy", "EpisodeReplay", "drqn_view", "load_drqn", "save_drqn",
           "td_targets", "train_drqn"]
