"""Search-network checkpoints: weights plus what is needed to trust and resume them (network
config, grid config, training config, seed, git revision, stage, metrics, optimiser state),
written atomically with a SHA-256 of the weights and read with torch.load(weights_only=True): a checkpoint is data, never
code, so a file from elsewhere cannot run anything when it is loaded."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import torch

from provenance import atomic_write_bytes, git_revision

from ..nn.checkpoint import CheckpointError, read_torch_document, weights_digest
from .config import SearchNetConfig
from .model import SearchNet

FORMAT = "uavsearch-searchnet/1"


def save_searchnet(path: str | Path, model: SearchNet, **state: Any) -> Path:
    """state: grid (dict), train (dict), seed, stage, metrics, optimizer, critic ... plain data only."""
    doc = {"format": FORMAT, "model_config": model.cfg.to_dict(), "state_dict": model.state_dict(),
           "git_revision": state.pop("git_revision", None) or git_revision(), **state}
    doc["weights_sha256"] = weights_digest(doc["state_dict"])
    buf = io.BytesIO()
    torch.save(doc, buf)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def read_searchnet(path: str | Path) -> dict[str, Any]:
    """The nn checkpoints' reader: weights only, format tag, keys and the weights' SHA-256."""
    return read_torch_document(path, FORMAT, ("model_config", "state_dict"))


def load_searchnet(path: str | Path) -> tuple[SearchNet, dict[str, Any]]:
    doc = read_searchnet(path)
    try:
        model = SearchNet(SearchNetConfig.from_dict(doc["model_config"]))
        model.load_state_dict(doc["state_dict"])
    except (TypeError, ValueError, KeyError, RuntimeError) as e:
        raise CheckpointError(f"{path}: weights do not fit a search network ({e})") from e
    model.eval()
    return model, doc
