"""Datasets survive a killed writer and refuse bad labels: a killed `synth --overwrite` keeps
the old dataset, orphans of killed writers are cleaned, and a label outside the actions is a
clear error naming the shard."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from policy.data import DatasetError, open_dataset, synthesize
from policy.data.shards import ShardWriter
from sim.gridworld import GridConfig

ROOT = Path(__file__).resolve().parents[3]


def test_a_killed_synth_overwrite_keeps_the_old_dataset(tmp_path: Path) -> None:
    ds = synthesize(GridConfig(), 30, 0, tmp_path / "ds", progress=False, shard_size=50)
    before = open_dataset(ds).load()[2].copy()
    p = subprocess.Popen([sys.executable, "-m", "missions", "synth", "--out", str(ds), "--episodes", "100000",
                          "--shard-size", "20", "--overwrite", "--quiet", "--seed", "5"], cwd=ROOT,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 60
        while time.monotonic() < end and not list(tmp_path.glob("ds.new-*/shard-*.npz")):
            time.sleep(0.2)  # the new dataset has started writing shards
        assert list(tmp_path.glob("ds.new-*/shard-*.npz")), "synth never started writing"
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    np.testing.assert_array_equal(open_dataset(ds).load()[2], before)  # the old one, whole
    # the next writer cleans what the killed one left
    (ds / ".shard-00000.npz.x1y2.tmp").write_bytes(b"half")
    synthesize(GridConfig(), 5, 1, ds, progress=False, overwrite=True)
    assert not list(tmp_path.glob("ds.new-*")) and not list(tmp_path.glob("ds.old-*"))
    assert not list(ds.glob(".*.tmp"))
    assert len(open_dataset(ds)) > 0


def test_labels_outside_the_actions_are_refused(tmp_path: Path) -> None:
    w = ShardWriter(tmp_path / "bad", shard_size=10)
    n = 6
    w.add(np.zeros((n, 3, 3, 3), np.uint8), np.zeros((n, 1, 10, 10), np.uint8), np.array([0, 1, 2, 3, 7, 0]),
          np.zeros(n, np.int64))
    w.close({"config": GridConfig().to_dict(), "seed": 0})
    with pytest.raises(DatasetError, match="label 7 outside the 4 actions"):
        open_dataset(tmp_path / "bad").load()


def test_pid_liveness_guard_keeps_a_running_writers_staging(tmp_path: Path) -> None:
    live = tmp_path / f"ds.new-{os.getpid()}"
    live.mkdir()
    dead = tmp_path / "ds.new-999999999"
    dead.mkdir()
    ShardWriter(tmp_path / "ds")
    assert live.exists() and not dead.exists()
