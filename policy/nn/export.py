"""TorchScript export for the policy service: one self-contained file, no Python classes needed."""

from __future__ import annotations

import io
from pathlib import Path

import torch
from torch import nn

from provenance import atomic_write_bytes

from .config import ModelConfig


def export_torchscript(model: nn.Module, cfg: ModelConfig, path: str | Path) -> Path:
    model = model.eval()
    example = (
        torch.zeros(1, *cfg.view_shape, dtype=torch.uint8),
        torch.zeros(1, *cfg.map_shape, dtype=torch.float32),
    )
    with torch.no_grad():
        traced = torch.jit.trace(model, example)
    buf = io.BytesIO()
    torch.jit.save(traced, buf, _extra_files={"model_config.json": repr(cfg.to_dict())})
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def load_torchscript(path: str | Path) -> torch.jit.ScriptModule:
    return torch.jit.load(str(path), map_location="cpu").eval()
