"""On-disk datasets of (I, M, a) samples: compressed .npz shards plus a meta.json written
last. A reader trusts nothing: every shard is checked against the sha256 and the shapes the
meta records, and any mismatch is a DatasetError that names the file."""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_write_bytes, atomic_write_json

FORMAT = "uavsearch-dataset/1"
META = "meta.json"
KEYS = ("views", "maps", "actions", "episode")


class DatasetError(ValueError):
    """A dataset that cannot be used as it is; the message says which file and why."""


def _clean_orphans(out: Path) -> None:
    """What a killed writer left: temporary files of atomic writes inside `out`, and staging or
    retired copies beside it (NAME.new-PID, NAME.old-PID) whose process is gone."""
    if out.is_dir():
        for tmp in out.glob(".*.tmp"):
            tmp.unlink(missing_ok=True)
    for side in list(out.parent.glob(f"{out.name}.new-*")) + list(out.parent.glob(f"{out.name}.old-*")):
        pid = side.name.rsplit("-", 1)[-1]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(side, ignore_errors=True)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class ShardWriter:
    """Buffers samples and writes a shard every `shard_size` samples.

    Replacing a dataset (overwrite=True) writes the new one beside it (NAME.new-PID) and swaps
    the directories only when it is complete: a writer killed half-way leaves the old dataset
    whole (it used to delete its meta first and overwrite its shards in place)."""

    def __init__(self, out: Path, shard_size: int = 100_000, overwrite: bool = False) -> None:
        if shard_size < 1:
            raise ValueError("shard_size must be >= 1")
        self.final = Path(out)
        if self.final.exists() and not self.final.is_dir():
            raise FileExistsError(f"{self.final} is a file, not a dataset directory")
        _clean_orphans(self.final)
        self.out = self.final
        if (self.final / META).exists():
            if not overwrite:
                raise FileExistsError(f"{self.final} already holds a dataset (overwrite=True replaces it)")
            self.out = self.final.with_name(f"{self.final.name}.new-{os.getpid()}")
            shutil.rmtree(self.out, ignore_errors=True)
        self.out.mkdir(parents=True, exist_ok=True)
        self.shard_size = shard_size
        self._buf: dict[str, list[np.ndarray]] = {k: [] for k in KEYS}
        self._n = 0
        self.shards: list[dict[str, Any]] = []

    def add(self, views: np.ndarray, maps: np.ndarray, actions: np.ndarray, episode: np.ndarray) -> None:
        for k, v in zip(KEYS, (views, maps, actions, episode), strict=True):
            self._buf[k].append(v)
        self._n += len(actions)
        while self._n >= self.shard_size:
            self._flush(self.shard_size)

    def _flush(self, count: int) -> None:
        arrays = {k: np.concatenate(v) for k, v in self._buf.items()}
        head = {k: a[:count] for k, a in arrays.items()}
        self._buf = {k: [a[count:]] for k, a in arrays.items()}
        self._n -= count
        bio = io.BytesIO()
        np.savez_compressed(bio, **head)
        data = bio.getvalue()
        name = f"shard-{len(self.shards):05d}.npz"
        atomic_write_bytes(self.out / name, data)
        self.shards.append({"file": name, "samples": count, "sha256": hashlib.sha256(data).hexdigest()})

    def close(self, meta: dict[str, Any]) -> Path:
        if self._n:
            self._flush(self._n)
        if not self.shards:
            raise DatasetError("no samples were written")
        first = np.load(self.out / self.shards[0]["file"])
        record = {
            "format": FORMAT,
            **meta,
            "samples": int(sum(s["samples"] for s in self.shards)),
            "view_shape": list(first["views"].shape[1:]),
            "map_shape": list(first["maps"].shape[1:]),
            "shards": self.shards,
        }
        atomic_write_json(self.out / META, record)
        keep = {s["file"] for s in self.shards}
        for stale in self.out.glob("shard-*.npz"):  # left by an interrupted, larger run
            if stale.name not in keep:
                stale.unlink()
        if self.out != self.final:  # the swap: old aside, new in place, old gone
            old = self.final.with_name(f"{self.final.name}.old-{os.getpid()}")
            os.replace(self.final, old)
            os.replace(self.out, self.final)
            shutil.rmtree(old, ignore_errors=True)
            self.out = self.final
        return self.final


class Dataset:
    def __init__(self, path: Path, meta: dict[str, Any]) -> None:
        self.path, self.meta = path, meta

    def __len__(self) -> int:
        return int(self.meta["samples"])

    @property
    def n_actions(self) -> int:
        return int(self.meta["config"].get("n_actions") or (5 if self.meta["config"]["motion"] != "static" else 4))

    def shard(self, i: int) -> dict[str, np.ndarray]:
        info = self.meta["shards"][i]
        f = self.path / info["file"]
        try:
            data = f.read_bytes()
        except FileNotFoundError:
            raise DatasetError(f"{f}: shard listed in {META} is missing") from None
        if hashlib.sha256(data).hexdigest() != info["sha256"]:
            raise DatasetError(f"{f}: checksum mismatch (corrupt or replaced shard)")
        try:
            with np.load(io.BytesIO(data)) as z:
                arrays = {k: z[k] for k in KEYS}
        except (zipfile.BadZipFile, KeyError, ValueError, OSError, EOFError) as e:
            raise DatasetError(f"{f}: unreadable shard ({e})") from e
        n = info["samples"]
        if any(len(a) != n for a in arrays.values()):
            raise DatasetError(f"{f}: holds arrays of different lengths, meta says {n}")
        if list(arrays["views"].shape[1:]) != self.meta["view_shape"] or list(
            arrays["maps"].shape[1:]
        ) != self.meta["map_shape"]:
            raise DatasetError(f"{f}: sample shapes differ from {META}")
        a = arrays["actions"]
        if len(a) and (a.min() < 0 or a.max() >= self.n_actions):
            bad = int(a[(a < 0) | (a >= self.n_actions)][0])
            raise DatasetError(f"{f}: label {bad} outside the {self.n_actions} actions 0..{self.n_actions - 1}")
        return arrays

    def load(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All samples in memory: (views uint8, maps uint8, actions int64)."""
        parts = [self.shard(i) for i in range(len(self.meta["shards"]))]
        return (
            np.concatenate([p["views"] for p in parts]),
            np.concatenate([p["maps"] for p in parts]),
            np.concatenate([p["actions"] for p in parts]).astype(np.int64),
        )

    def iter_batches(
        self, batch_size: int, shuffle: bool = True, seed: int = 0
    ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Stream batches reading one shard at a time (shard order and the samples within a
        shard shuffled when asked). Batches run across shard boundaries, so all but the last
        hold exactly batch_size samples."""
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1 (got {batch_size})")
        rng = np.random.default_rng(seed)
        order = np.arange(len(self.meta["shards"]))
        if shuffle:
            rng.shuffle(order)
        left: list[np.ndarray] | None = None
        for i in order:
            s = self.shard(int(i))
            idx = rng.permutation(len(s["actions"])) if shuffle else np.arange(len(s["actions"]))
            cur = [s["views"][idx], s["maps"][idx], s["actions"][idx]]
            if left is not None:
                cur = [np.concatenate([a, b]) for a, b in zip(left, cur, strict=True)]
            full = len(cur[2]) // batch_size * batch_size
            for b in range(0, full, batch_size):
                yield cur[0][b : b + batch_size], cur[1][b : b + batch_size], cur[2][
                    b : b + batch_size
                ].astype(np.int64)
            left = [a[full:] for a in cur]
        if left is not None and len(left[2]):
            yield left[0], left[1], left[2].astype(np.int64)


def open_dataset(path: str | Path) -> Dataset:
    path = Path(path)
    meta_file = path / META
    if not meta_file.exists():
        raise DatasetError(f"{path}: no {META} (not a dataset, or its synthesis did not finish)")
    try:
        meta = json.loads(meta_file.read_text())
    except json.JSONDecodeError as e:
        raise DatasetError(f"{meta_file}: not valid JSON ({e})") from e
    if meta.get("format") != FORMAT:
        raise DatasetError(f"{meta_file}: format {meta.get('format')!r}, expected {FORMAT!r}")
    for key in ("config", "samples", "shards", "view_shape", "map_shape"):
        if key not in meta:
            raise DatasetError(f"{meta_file}: missing field {key!r}")
    return Dataset(path, meta)
