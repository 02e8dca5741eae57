"""DRQN checkpoints: weights with the configs, seed, git revision and training record, written
atomically; anything unreadable, foreign or inconsistent is a DrqnCheckpointError."""

from __future__ import annotations

import io
import pickle
import zipfile
from pathlib import Path
from typing import Any

import torch

from provenance import atomic_write_bytes, git_revision
from sim.gridworld import GridConfig

from .config import DrqnConfig
from .network import DrqnNet

FORMAT = "uavsearch-drqn/1"
#: the shipped checkpoint (static random targets, 10 x 10, 5 targets)
DEFAULT_CHECKPOINT = Path(__file__).resolve().parent.parent / "checkpoints" / "drqn_static_random.pt"


class DrqnCheckpointError(ValueError):
    """A DRQN checkpoint that cannot be used; the message names the file and the reason."""


def save_drqn(
    path: str | Path, net: DrqnNet, grid: GridConfig, seed: int, half: bool = False, **record: Any
) -> Path:
    """record: plain data only (numbers, strings, lists, dicts): training stats, progress.
    half stores the weights as float16 (half the size, for shipping); loading restores float32."""
    weights = {k: v.half() if half and v.is_floating_point() else v for k, v in net.state_dict().items()}
    doc = {
        "format": FORMAT,
        "drqn_config": net.cfg.to_dict(),
        "grid_config": grid.to_dict(),
        "seed": int(seed),
        "git_revision": git_revision(),
        "weights_dtype": "float16" if half else "float32",
        "state_dict": weights,
        **record,
    }
    buf = io.BytesIO()
    torch.save(doc, buf)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def read_drqn(path: str | Path) -> dict[str, Any]:
    path = Path(path)
    if not path.is_file():
        raise DrqnCheckpointError(f"{path}: no such checkpoint file")
    try:
        doc = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile, ValueError, OSError) as e:
        raise DrqnCheckpointError(f"{path}: not a readable checkpoint ({type(e).__name__}: {e})") from e
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise DrqnCheckpointError(f"{path}: not a DRQN checkpoint (format {got!r}, want {FORMAT!r})")
    for key in ("drqn_config", "grid_config", "state_dict", "seed"):
        if key not in doc:
            raise DrqnCheckpointError(f"{path}: missing {key!r}")
    return doc


def load_drqn(path: str | Path = DEFAULT_CHECKPOINT) -> tuple[DrqnNet, dict[str, Any]]:
    """The network (eval mode) and the checkpoint's record."""
    doc = read_drqn(path)
    try:
        cfg = DrqnConfig.from_dict(doc["drqn_config"])
        net = DrqnNet(cfg)
        net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in doc["state_dict"].items()})
    except (ValueError, TypeError, RuntimeError, AttributeError, KeyError) as e:
        raise DrqnCheckpointError(f"{path}: weights do not fit the stored config ({e})") from e
    net.eval()
    return net, doc
