"""Training the networks on ground-truth datasets (k-fold, resumable, logged)."""

from .log import MetricsLog
from .train import TrainConfig, pick_device, train

__all__ = ["MetricsLog", "TrainConfig", "pick_device", "train"]
