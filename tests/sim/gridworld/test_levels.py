"""Altitude levels in the grid world (issue 27): the paper's world unchanged by default, the
detection table validated, climb/descend, recovery at level 1 only, detections drawn per
episode (reproducible, independent of the batch) at the table's rates."""

from __future__ import annotations

import json

import numpy as np
import pytest

from sim.gridworld import (
    Action,
    BatchGridWorld,
    ConfigError,
    DetectionTable,
    GridConfig,
    GridSearchEnv,
    level_height_m,
    sample_episodes,
)
from sim.gridworld import detection as detection_mod

TABLE = DetectionTable(((1, 1), (0.95, 0.9, 0.8), (0.85, 0.75, 0.6, 0.45)), (0, 0.002, 0.005))


def test_default_config_is_the_papers_world():
    cfg = GridConfig()
    assert cfg.levels == 1 and cfg.detection is None and cfg.perfect_detection
    assert cfg.n_actions == 4 and GridConfig(motion="random_walk").n_actions == 5
    assert "levels" not in cfg.to_dict() and "detection" not in cfg.to_dict()
    assert (Action.CLIMB, Action.DESCEND) == (5, 6)
    assert GridConfig.from_dict(GridConfig(levels=2, detection=TABLE).to_dict()).detection == TABLE


def test_levels_without_a_table_names_the_missing_file(tmp_path, monkeypatch):
    missing = tmp_path / "detection.json"
    monkeypatch.setattr(detection_mod, "DEFAULT_TABLE", missing)
    with pytest.raises(ConfigError, match="detection.json"):
        GridConfig(levels=3)
    with pytest.raises(ConfigError, match="levels must be in 1..3"):
        GridConfig(levels=4, detection=TABLE)
    with pytest.raises(ConfigError, match="1 level"):
        GridConfig(levels=2, detection=DetectionTable.perfect(1))


def test_table_file_round_trip_and_validation(tmp_path):
    path = tmp_path / "t.json"
    path.write_text(json.dumps(TABLE.to_dict()))
    assert DetectionTable.load(path) == TABLE
    assert TABLE.height_m == pytest.approx((3.5, 5.8333, 8.1667), abs=1e-3)
    assert level_height_m(3) == pytest.approx(8.1667, abs=1e-3)
    bad = TABLE.to_dict() | {"format": "x"}
    with pytest.raises(ConfigError, match="format"):
        DetectionTable.from_dict(bad)
    with pytest.raises(ConfigError, match="rings"):
        DetectionTable.from_dict(TABLE.to_dict() | {"p_detect": [[1, 1], [1, 1], [1, 1, 1, 1]]})
    with pytest.raises(ConfigError, match=r"\[0, 1\]"):
        DetectionTable.from_dict(TABLE.to_dict() | {"p_detect": [[1, 1.2], [1, 1, 1], [1, 1, 1, 1]]})
    with pytest.raises(ConfigError, match="no detection table"):
        DetectionTable.load(tmp_path / "none.json")


def _play(cfg, n=40, steps=40, seed=3):
    ep = sample_episodes(cfg, n, seed)
    w = BatchGridWorld(ep, seed)
    rng = np.random.default_rng(9)
    out = []
    for _ in range(steps):
        v, m = w.observe()
        out.append((v.copy(), m.copy(), w.t.copy(), w.found.copy()))
        w.step(rng.integers(0, 4, n))
    return out


def test_perfect_level_one_table_is_todays_world_bit_for_bit():
    for a, b in zip(_play(GridConfig()), _play(GridConfig(detection=DetectionTable.perfect(1))), strict=True):
        for x, y in zip(a, b, strict=True):
            assert np.array_equal(x, y)


def test_climb_descend_recovery_only_at_level_one_and_flight_time():
    cfg = GridConfig(levels=2, detection=DetectionTable.perfect(2))
    ep = sample_episodes(cfg, 1, 0)
    w = BatchGridWorld(ep, 0)
    assert w.valid_actions()[0, Action.CLIMB] and not w.valid_actions()[0, Action.DESCEND]
    assert not w.valid_actions()[0, Action.N]  # static targets: no stay, as the paper's A
    w.step(np.array([Action.CLIMB]))
    assert w.level[0] == 2 and w.t[0] == 1 and np.array_equal(w.agent, ep.agent)
    assert w.flight_s[0] == pytest.approx(level_height_m(2) - level_height_m(1))
    # fly onto a target's cell at level 2: not recovered until the agent descends
    tx, ty = ep.targets[0, 0]
    w.agent[0] = (tx - 1, ty) if tx > 0 else (tx + 1, ty)
    w.step(np.array([Action.R if tx > 0 else Action.L]))
    assert tuple(w.agent[0]) == (tx, ty) and not w.found[0].any()
    assert not w.visited[0, ty, tx]  # the map marks cells flown over at level 1 only
    w.step(np.array([Action.DESCEND]))
    assert w.level[0] == 1 and w.found[0, 0] and w.find_moves[0, 0] == w.t[0] == 3
    assert w.flight_s[0] == pytest.approx(2 * (level_height_m(2) - level_height_m(1)) + 1.0)


def _climbs(cfg, ep, seed, steps=8):
    w = BatchGridWorld(ep, seed)
    seen = []
    for k in range(steps):
        seen.append(w.observe()[0][:, 0].copy())
        w.step(np.full(len(ep), Action.CLIMB if k % 2 == 0 else Action.DESCEND))
    return np.stack(seen, axis=1)


def test_detections_are_per_episode_streams_independent_of_the_batch():
    cfg = GridConfig(width=12, height=12, n_targets=20, levels=3, detection=TABLE)
    ep = sample_episodes(cfg, 20, 11)
    whole = _climbs(cfg, ep, 11)
    part = _climbs(cfg, ep.subset(slice(5, 9)), 11 + 5)
    assert np.array_equal(whole[5:9], part)
    assert np.array_equal(whole, _climbs(cfg, ep, 11))
    v, _ = BatchGridWorld(ep, 11).observe()
    assert v.shape == (20, 4, 7, 7)
    assert not v[:, 3, 2:5, 2:5].any() and v[:, 3, 0].any()  # level 1: only the 3 x 3 is in view


def test_detection_rates_follow_the_table():
    cfg = GridConfig(width=15, height=15, n_targets=40, levels=3, detection=TABLE)
    ep = sample_episodes(cfg, 3000, 5)
    w = BatchGridWorld(ep, 5)
    w.step(np.full(len(ep), Action.CLIMB))
    w.step(np.full(len(ep), Action.CLIMB))  # level 3
    det, _ = w.observe()
    tg = w.targets()
    occ = np.zeros((len(ep), 15, 15), bool)
    occ[np.arange(len(ep))[:, None], tg[..., 1], tg[..., 0]] = True
    off = np.arange(-3, 4)
    ys, xs = w.agent[:, 1, None] + off, w.agent[:, 0, None] + off
    inside = ((ys >= 0) & (ys < 15))[:, :, None] & ((xs >= 0) & (xs < 15))[:, None, :]
    truth = occ[np.arange(len(ep))[:, None, None], np.clip(ys, 0, 14)[:, :, None], np.clip(xs, 0, 14)[:, None, :]]
    truth &= inside
    ring = np.maximum(np.abs(off)[:, None], np.abs(off)[None, :])
    d = det[:, 0].astype(bool)
    for k, p in enumerate(TABLE.p_detect[2]):
        sel = truth & (ring == k)[None]
        if sel.sum() < 300:  # the agent never starts on a target: ring 0 is empty here
            continue
        assert d[sel].mean() == pytest.approx(p, abs=0.04), k
    empty = inside & ~truth
    assert d[empty].mean() == pytest.approx(0.005, abs=0.002)


def test_env_with_levels():
    env = GridSearchEnv(GridConfig(levels=2, detection=DetectionTable.perfect(2)))
    obs, info = env.reset(seed=1)
    assert obs["view"].shape == (4, 5, 5) and obs["level"] == 1 and info["flight_s"] == 0.0
    assert env.observation_space.contains(obs)
