"""A checkpoint is data: loading one never runs code from it, and flipped bytes in its weights
are a clear error, not a quietly different policy."""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import pytest
import torch

from policy.nn import CheckpointError, load_model, save_checkpoint
from policy.nn.config import ModelConfig
from policy.nn.models import build_model


def _saved(tmp_path: Path) -> Path:
    cfg = ModelConfig()
    return save_checkpoint(tmp_path / "m.pt", build_model(cfg), cfg, seed=0)


def _flip_largest_tensor(path: Path) -> None:
    raw = bytearray(path.read_bytes())
    with zipfile.ZipFile(io.BytesIO(bytes(raw))) as z:
        info = max((i for i in z.infolist() if "/data/" in i.filename), key=lambda i: i.file_size)
        start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    for k in range(64):  # 64 bytes in the middle of the largest tensor, as the probe did
        raw[start + info.file_size // 2 + k] ^= 0x5A
    path.write_bytes(bytes(raw))


def test_flipped_weight_bytes_are_caught(tmp_path: Path) -> None:
    path = _saved(tmp_path)
    load_model(path)  # intact: loads
    _flip_largest_tensor(path)
    with pytest.raises(CheckpointError, match="SHA-256"):
        load_model(path)


def test_flipped_bytes_in_a_shipped_searchnet_are_caught(tmp_path: Path) -> None:
    from policy.nn import shipped_checkpoint
    from policy.searchnet.checkpoint import load_searchnet

    path = tmp_path / "searchnet.pt"
    path.write_bytes(shipped_checkpoint("searchnet_static_random").read_bytes())
    assert load_searchnet(path)[1]["weights_sha256"], "shipped with its checksum"
    _flip_largest_tensor(path)
    with pytest.raises(CheckpointError, match="SHA-256"):
        load_searchnet(path)


class _Payload:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return (Path.write_text, (self.marker, "pwned"))


def test_a_checkpoint_that_carries_code_is_refused_without_running_it(tmp_path: Path) -> None:
    marker = tmp_path / "marker"
    path = tmp_path / "evil.pt"
    torch.save({"format": "uavsearch-checkpoint/1", "model_config": {}, "state_dict": {}, "x": _Payload(marker)}, path)
    with pytest.raises(CheckpointError, match="not a readable checkpoint"):
        load_model(path)
    assert not marker.exists(), "loading ran code from the file"
