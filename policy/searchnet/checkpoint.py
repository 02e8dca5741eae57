"""Search-network checkpoints: weights plus what is needed to trust and resume them (network
config, grid config, training config, seed, git revision, stage, metrics, optimiser state),
written atomically and read with torch.load(weights_only=True): a checkpoint is data, never
code, so a file from elsewhere cannot run anything when it is loaded."""

from __future__ import annotations

import io
import pickle
import zipfile
from pathlib import Path
from typing import Any

import torch

from provenance import atomic_write_bytes, git_revision

from ..nn.checkpoint import CheckpointError
from .config import SearchNetConfig
from .model import SearchNet

FORMAT = "uavsearch-searchnet/1"


def save_searchnet(path: str | Path, model: SearchNet, **state: Any) -> Path:
    """state: grid (dict), train (dict), seed, stage, metrics, optimizer, critic ... plain data only."""
    doc = {"format": FORMAT, "model_config": model.cfg.to_dict(), "state_dict": model.state_dict(),
           "git_revision": state.pop("git_revision", None) or git_revision(), **state}
    buf = io.BytesIO()
    torch.save(doc, buf)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def read_searchnet(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint file")
    try:
        doc = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile, ValueError, OSError) as e:
        raise CheckpointError(f"{path}: not a readable checkpoint ({type(e).__name__}: {e})") from e
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise CheckpointError(f"{path}: not a searchnet checkpoint of format {FORMAT!r} (found {found!r})")
    for key in ("model_config", "state_dict"):
        if key not in doc:
            raise CheckpointError(f"{path}: missing {key!r}")
    return doc


def load_searchnet(path: str | Path) -> tuple[SearchNet, dict[str, Any]]:
    doc = read_searchnet(path)
    try:
        model = SearchNet(SearchNetConfig.from_dict(doc["model_config"]))
        model.load_state_dict(doc["state_dict"])
    except (TypeError, ValueError, KeyError, RuntimeError) as e:
        raise CheckpointError(f"{path}: weights do not fit a search network ({e})") from e
    model.eval()
    return model, doc
