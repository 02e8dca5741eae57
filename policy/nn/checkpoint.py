"""Checkpoints: weights plus everything needed to trust and resume them (model config, grid
config, training config, seed, git revision, metrics, optimiser and RNG state), written
atomically; a file that is corrupt, foreign or for another architecture is a clear error."""

from __future__ import annotations

import io
import pickle
import zipfile
from pathlib import Path
from typing import Any

import torch
from torch import nn

from provenance import atomic_write_bytes, git_revision

from .config import ModelConfig
from .models import build_model

FORMAT = "uavsearch-checkpoint/1"


class CheckpointError(ValueError):
    """A checkpoint that cannot be used; the message names the file and the reason."""


def save_checkpoint(path: str | Path, model: nn.Module, model_cfg: ModelConfig, **state: Any) -> Path:
    """state: grid config dict, train config dict, seed, metrics, optimizer, rng, epoch, fold..."""
    doc = {
        "format": FORMAT,
        "model_config": model_cfg.to_dict(),
        "state_dict": model.state_dict(),
        "git_revision": git_revision(),
        **state,
    }
    buf = io.BytesIO()
    torch.save(doc, buf)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def read_torch_document(path: str | Path, fmt: str, required: tuple[str, ...]) -> dict[str, Any]:
    """Load a torch-saved dict and check its format tag and keys; any failure is a CheckpointError."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint file")
    try:
        doc = torch.load(path, map_location="cpu", weights_only=False)
    except (RuntimeError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile, ValueError, OSError) as e:
        raise CheckpointError(f"{path}: not a readable checkpoint ({type(e).__name__}: {e})") from e
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise CheckpointError(f"{path}: not a uavsearch checkpoint of format {fmt!r} (found {found!r})")
    for key in required:
        if key not in doc:
            raise CheckpointError(f"{path}: missing {key!r}")
    return doc


def read_checkpoint(path: str | Path) -> dict[str, Any]:
    return read_torch_document(path, FORMAT, ("model_config", "state_dict"))


def load_model(path: str | Path, expect: ModelConfig | None = None) -> tuple[nn.Module, dict[str, Any]]:
    """Rebuild the network from a checkpoint; `expect` guards against the wrong architecture."""
    doc = read_checkpoint(path)
    try:
        cfg = ModelConfig.from_dict(doc["model_config"])
    except (TypeError, ValueError, KeyError) as e:
        raise CheckpointError(f"{path}: bad model config ({e})") from e
    if expect is not None and (cfg.model, cfg.arch, cfg.view_shape, cfg.map_shape, cfg.n_actions) != (
        expect.model, expect.arch, expect.view_shape, expect.map_shape, expect.n_actions
    ):
        raise CheckpointError(f"{path}: holds a {cfg} network, expected {expect}")
    model = build_model(cfg)
    try:
        model.load_state_dict(doc["state_dict"])
    except (RuntimeError, KeyError) as e:
        raise CheckpointError(f"{path}: weights do not fit the {cfg.arch} {cfg.model} network ({e})") from e
    model.eval()
    doc["model_config"] = cfg
    return model, doc
