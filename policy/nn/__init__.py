"""The dual-stream network, the SSN baseline, checkpoints, export and batch inference."""

from .checkpoint import CheckpointError, load_model, read_checkpoint, save_checkpoint
from .config import ARCHS, MODELS, ModelConfig
from .encode import map_scale_for, normalise, to_tensors, view_scale_for
from .export import export_torchscript, load_torchscript
from .infer import NetworkPolicy, load_policy, load_shipped_policy, shipped_checkpoint
from .models import DualStream, SplitStream, build_model

__all__ = [
    "ARCHS", "CheckpointError", "DualStream", "MODELS", "ModelConfig", "NetworkPolicy",
    "SplitStream", "build_model", "export_torchscript", "load_model", "load_policy",
    "load_shipped_policy", "load_torchscript", "map_scale_for", "normalise", "read_checkpoint",
    "save_checkpoint", "shipped_checkpoint", "to_tensors", "view_scale_for",
]
