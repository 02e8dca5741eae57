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


def test_batches_are_full_across_shard_boundaries(tmp_path: Path) -> None:
    ds = open_dataset(synthesize(GridConfig(), 40, 2, tmp_path / "ds", shard_size=170, progress=False))
    assert len(ds.meta["shards"]) > 2
    for shuffle in (False, True):
        sizes = [len(a) for _, _, a in ds.iter_batches(64, shuffle=shuffle, seed=3)]
        assert sum(sizes) == len(ds) and set(sizes[:-1]) == {64} and 0 < sizes[-1] <= 64
    ordered = np.concatenate([a for _, _, a in ds.iter_batches(50, shuffle=False)])
    assert (ordered == ds.load()[2]).all()
    with pytest.raises(ValueError, match="batch_size"):
        next(ds.iter_batches(0))


def test_tampered_shard_or_meta_names_the_file(tmp_path: Path) -> None:
    out = synthesize(GridConfig(), 30, 1, tmp_path / "ds", shard_size=200, progress=False)
    shard = out / "shard-00000.npz"
    good = bytearray(shard.read_bytes())
    bad = good.copy()
    bad[len(bad) // 2] ^= 0xFF  # one flipped byte, same length
    shard.write_bytes(bytes(bad))
    with pytest.raises(DatasetError, match="shard-00000.npz.*checksum"):
        open_dataset(out).load()
    shard.write_bytes(bytes(good))
    meta = json.loads((out / "meta.json").read_text())
    meta["shards"][0]["samples"] += 1
    (out / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(DatasetError, match="shard-00000.npz.*different lengths"):
        open_dataset(out).load()


def test_overwrite_replaces_the_whole_dataset(tmp_path: Path) -> None:
    synthesize(GridConfig(), 40, 1, tmp_path / "ds", shard_size=100, progress=False)
    out = synthesize(GridConfig(), 5, 2, tmp_path / "ds", shard_size=100, progress=False, overwrite=True)
    ds = open_dataset(out)
    assert ds.meta["seed"] == 2 and ds.meta["episodes"] == 5
    assert sorted(p.name for p in out.glob("shard-*.npz")) == [s["file"] for s in ds.meta["shards"]]
    (tmp_path / "f").write_text("x")
    with pytest.raises(FileExistsError, match="is a file"):
        synthesize(GridConfig(), 5, 2, tmp_path / "f", progress=False)


def test_views_from_the_simulated_camera(tmp_path: Path) -> None:
    from sim.vehicle import ViewRenderer  # the +S sensor, plugged in through view_fn

    cfg = GridConfig()
    r = ViewRenderer(cfg.width, cfg.height, cfg.n_targets, image=50, seed=0)
    try:
        def camera(world: BatchGridWorld) -> np.ndarray:
            return r.render_views(world.targets(), world.agent, cfg.width, cfg.height)

        out = synthesize(cfg, 3, 4, tmp_path / "ds", view_fn=camera, progress=False)
        ds = open_dataset(out)
        views, maps, actions = ds.load()
        assert ds.meta["rendered"] and ds.meta["view_shape"] == [3, 50, 50]
        assert views.shape == (len(actions), 3, 50, 50) and views.dtype == np.uint8
        start = BatchGridWorld(sample_episodes(cfg, 3, chunk_seed(4, 0)), 0)
        assert (views[0] == camera(start)[0]).all()
        assert views.std() > 0, "frames show the field, not a blank image"
        with pytest.raises(ValueError, match=r"view_fn must return \(n=3, 3, H, W\) uint8"):
            synthesize(cfg, 3, 4, tmp_path / "bad", progress=False,
                       view_fn=lambda w: camera(w).astype(np.float32))
        assert not (tmp_path / "bad" / "meta.json").exists()
    finally:
        r.close()
