"""Checkpoints: weights plus everything needed to trust and resume them (model config, grid
config, training config, seed, git revision, metrics, optimiser and RNG state), written
atomically; a file that is corrupt, foreign or for another architecture is a clear error.

Loading never runs code from the file (torch.load(weights_only=True), with numpy's array and
dtype types allowed for replay buffers and RNG states), and the weights carry a SHA-256 that is
checked on load: torch's zip reader does not check its CRCs, so flipped bytes in a tensor used
to load silently and change results."""

from __future__ import annotations

import hashlib
import io
import logging
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
#: torch.save writes a zip archive; files from torch < 1.6 are a bare pickle (protocol marker)
_ZIP_MAGIC = b"PK\x03\x04"
_PICKLE_PROTO = b"\x80"
log = logging.getLogger(__name__)


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
    doc["weights_sha256"] = weights_digest(doc["state_dict"])
    buf = io.BytesIO()
    torch.save(doc, buf)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def weights_digest(state_dict: dict[str, Any]) -> str:
    """SHA-256 over the tensors' names, dtypes, shapes and bytes, in name order."""
    h = hashlib.sha256()
    for name in sorted(state_dict):
        t = state_dict[name]
        if not isinstance(t, torch.Tensor):
            continue
        t = t.detach().cpu().contiguous()
        h.update(f"{name}|{t.dtype}|{tuple(t.shape)}|".encode())
        h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b"")
    return h.hexdigest()


def _safe_globals() -> list:
    """numpy types a training snapshot may hold (replay buffers, RNG state): data, not code."""
    import numpy as np

    core = getattr(np, "_core", None) or np.core
    dtypes = [type(np.dtype(t)) for t in (np.float16, np.float32, np.float64, np.int8, np.int16, np.int32, np.int64,
                                          np.uint8, np.uint16, np.uint32, np.uint64, np.bool_)]
    return [core.multiarray._reconstruct, core.multiarray.scalar, np.ndarray, np.dtype, *dtypes]


def read_torch_document(path: str | Path, fmt: str, required: tuple[str, ...]) -> dict[str, Any]:
    """Load a torch-saved dict (weights only: no code in the file runs) and check its format tag,
    keys and weights checksum; any failure is a CheckpointError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no such checkpoint file")
    try:
        with path.open("rb") as f:
            head = f.read(len(_ZIP_MAGIC))
    except OSError as e:
        raise CheckpointError(f"{path}: cannot be read ({e.strerror})") from e
    if not head:
        raise CheckpointError(f"{path}: is empty, not a checkpoint")
    if head != _ZIP_MAGIC and head[:1] != _PICKLE_PROTO:
        raise CheckpointError(f"{path}: not a readable checkpoint (it starts with {head!r}, "
                              f"not a torch.save zip archive)")
    try:
        with torch.serialization.safe_globals(_safe_globals()):
            doc = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile, ValueError, OSError, IndexError,
            KeyError, TypeError, AttributeError, UnicodeDecodeError, MemoryError) as e:
        # torch's readers fail on foreign bytes in many ways (an IndexError from the legacy
        # reader on text); its messages run to paragraphs: keep the first line
        first = str(e).strip().splitlines()[0][:160] if str(e).strip() else ""
        raise CheckpointError(f"{path}: not a readable checkpoint ({type(e).__name__}: {first})") from e
    if not isinstance(doc, dict) or doc.get("format") != fmt:
        found = doc.get("format") if isinstance(doc, dict) else None
        raise CheckpointError(f"{path}: not a uavsearch checkpoint of format {fmt!r} (found {found!r})")
    for key in required:
        if key not in doc:
            raise CheckpointError(f"{path}: missing {key!r}")
    want = doc.get("weights_sha256")
    if want is not None and isinstance(doc.get("state_dict"), dict) and weights_digest(doc["state_dict"]) != want:
        raise CheckpointError(f"{path}: the weights do not match their SHA-256 (the file is corrupt)")
    if want is None and "state_dict" in doc:
        log.info("%s: written before checksums; weights not verified", path)
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
