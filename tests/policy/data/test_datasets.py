import json
from pathlib import Path

import numpy as np
import pytest

from policy.data import DatasetError, open_dataset, synthesize
from policy.data.synth import chunk_seed
from policy.groundtruth import optimal_lengths
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


def test_round_trip_and_samples_are_the_optimal_decisions(tmp_path: Path) -> None:
    cfg = GridConfig()
    out = synthesize(cfg, 300, seed=3, out=tmp_path / "ds", shard_size=1000, chunk=150, progress=False)
    ds = open_dataset(out)
    views, maps, actions = ds.load()
    assert len(ds) == len(actions) == ds.meta["samples"]
    assert len(ds.meta["shards"]) == -(-len(ds) // 1000)
    assert ds.meta["git_revision"] and ds.meta["seed"] == 3 and ds.meta["config"]["width"] == 10
    # one sample per move of the optimal solution of every episode
    total = sum(int(optimal_lengths(sample_episodes(cfg, 150, chunk_seed(3, c))).sum()) for c in range(2))
    assert len(actions) == total
    assert views.shape[1:] == (3, 3, 3) and maps.shape[1:] == (1, 10, 10)
    assert set(np.unique(maps)) <= {0, 1, 10}
    assert (maps == 10).sum(axis=(1, 2, 3)).tolist() == [1] * len(maps)
    # streaming gives the same multiset of samples
    streamed = np.concatenate([a for _, _, a in ds.iter_batches(64, shuffle=True, seed=1)])
    assert sorted(streamed.tolist()) == sorted(actions.tolist())


def test_first_sample_of_each_episode_matches_the_world(tmp_path: Path) -> None:
    cfg = GridConfig(map_variant="memory", distribution="gaussian")
    out = synthesize(cfg, 50, seed=8, out=tmp_path / "ds", chunk=50, progress=False)
    views, maps, _ = open_dataset(out).load()
    ep_ids = np.concatenate([np.load(out / s["file"])["episode"] for s in open_dataset(out).meta["shards"]])
    world = BatchGridWorld(sample_episodes(cfg, 50, chunk_seed(8, 0)), 0)
    v0, m0 = world.observe()
    first = np.array([np.argmax(ep_ids == e) for e in range(50)])
    assert (views[first] == v0).all() and (maps[first] == m0.astype(np.uint8)).all()


def test_same_seed_same_dataset(tmp_path: Path) -> None:
    cfg = GridConfig(motion="herd", distribution="equidistant", map_variant="spatiotemporal")
    a = open_dataset(synthesize(cfg, 40, 5, tmp_path / "a", progress=False)).load()
    b = open_dataset(synthesize(cfg, 40, 5, tmp_path / "b", progress=False)).load()
    assert all((x == y).all() for x, y in zip(a, b, strict=True))
    assert a[1].shape[1] == 2 and set(np.unique(a[2])) <= set(range(5))


def test_corrupt_missing_and_foreign_data_are_clear_errors(tmp_path: Path) -> None:
    out = synthesize(GridConfig(), 60, 1, tmp_path / "ds", shard_size=500, progress=False)
    shard = out / "shard-00001.npz"
    good = shard.read_bytes()
    shard.write_bytes(good[: len(good) // 2])
    with pytest.raises(DatasetError, match="shard-00001.npz.*checksum"):
        open_dataset(out).load()
    shard.unlink()
    with pytest.raises(DatasetError, match="missing"):
        open_dataset(out).load()
    shard.write_bytes(good)
    open_dataset(out).load()  # restored: fine again
    with pytest.raises(DatasetError, match="no meta.json"):
        open_dataset(tmp_path)
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "meta.json").write_text("{not json")
    with pytest.raises(DatasetError, match="not valid JSON"):
        open_dataset(tmp_path / "bad")
    (tmp_path / "bad" / "meta.json").write_text(json.dumps({"format": "other"}))
    with pytest.raises(DatasetError, match="format"):
        open_dataset(tmp_path / "bad")


def test_existing_dataset_is_not_overwritten_silently(tmp_path: Path) -> None:
    synthesize(GridConfig(), 5, 1, tmp_path / "ds", progress=False)
    before = (tmp_path / "ds" / "meta.json").read_text()
    with pytest.raises(FileExistsError):
        synthesize(GridConfig(), 5, 2, tmp_path / "ds", progress=False)
    assert (tmp_path / "ds" / "meta.json").read_text() == before
