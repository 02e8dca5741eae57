"""Training the networks on ground-truth datasets (k-fold, resumable, logged, distributable)."""

from .kfold import kfold_split
from .metrics_log import MetricsLog, write_merged
from .plots import plot_runs, plot_training_curve
from .train import Data, TrainConfig, fit_fold, load_data, pick_device, train

__all__ = [
    "Data", "MetricsLog", "TrainConfig", "fit_fold", "kfold_split", "load_data", "pick_device",
    "plot_runs", "plot_training_curve", "train", "write_merged",
]
