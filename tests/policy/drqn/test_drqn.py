from pathlib import Path

import numpy as np
import pytest
import torch

from policy.drqn import (
    Drqn,
    DrqnConfig,
    DrqnLearner,
    DrqnPolicy,
    EpisodeReplay,
    drqn_view,
    load_drqn,
    td_targets,
    train_drqn,
)
from policy.evaluation import evaluate
from policy.nn import CheckpointError
from sim.gridworld import GridConfig


def test_view_colours_and_size() -> None:
    views = np.zeros((1, 3, 3, 3), dtype=np.uint8)
    views[0, 1, 0, :] = 1  # off-map top row
    views[0, 0, 2, 2] = 1  # a target bottom-right
    found = np.zeros((1, 3, 3), dtype=bool)
    img = drqn_view(views, found, 84)
    assert img.shape == (1, 3, 84, 84)
    assert (img[0, :, 0, 0] == 255).all(), "white outside the map"
    assert tuple(img[0, :, 83, 83]) == (255, 0, 0)
    found[0, 2, 2] = True
    assert tuple(drqn_view(views, found, 84)[0, :, 83, 83]) == (0, 0, 255), "found targets look different"


def test_network_shapes_and_hidden_state_carry() -> None:
    torch.manual_seed(0)
    net = Drqn(4, 84).eval()
    x = torch.randint(0, 255, (2, 5, 3, 84, 84), dtype=torch.uint8)
    with torch.no_grad():
        q_all, _ = net(x)
        state, steps = None, []
        for t in range(5):
            q, state = net(x[:, t : t + 1], state)
            steps.append(q)
    assert q_all.shape == (2, 5, 4)
    assert torch.allclose(q_all, torch.cat(steps, dim=1), atol=1e-5), "stepping with state == whole sequence"


def test_double_dqn_target_on_a_hand_made_example() -> None:
    online = torch.tensor([[[1.0, 5.0, 2.0, 0.0]]])
    target = torch.tensor([[[9.0, 3.0, 7.0, 1.0]]])
    y = td_targets(online, target, torch.tensor([[1.0]]), torch.tensor([[0.0]]), 0.5)
    assert y.item() == pytest.approx(1.0 + 0.5 * 3.0), "online picks action 1, target values it at 3"
    y_done = td_targets(online, target, torch.tensor([[1.0]]), torch.tensor([[1.0]]), 0.5)
    assert y_done.item() == 1.0


def test_replay_sampling_shapes() -> None:
    rb = EpisodeReplay(3, np.random.default_rng(0))
    for length in (5, 12, 20, 30):
        rb.add(np.zeros((length, 3, 3, 3), np.uint8), np.zeros((length, 3, 3), bool), np.arange(length) % 4,
               np.zeros(length))
    assert len(rb.episodes) == 3, "capacity in episodes"
    v, f, a, r, d, m = rb.sample(4, 8)
    assert v.shape == (4, 9, 3, 3, 3) and a.shape == (4, 8) and m.shape == (4, 8)


def test_short_training_checkpoint_and_policy(tmp_path: Path) -> None:
    grid = GridConfig(width=5, height=5, n_targets=2)
    cfg = DrqnConfig(image=42, episodes=32, envs=8, warmup_steps=100, eps_anneal_steps=200, train_max_steps=40)
    path = train_drqn(cfg, grid, tmp_path, seed=1, progress=False)
    net, doc = load_drqn(path)
    assert doc["updates"] > 0 and all(np.isfinite(doc["loss_curve"]))
    r = evaluate(DrqnPolicy.load(path), grid, 50, seed=2, progress=False)
    assert r.moves.shape == (50,) and (r.moves <= grid.t_e + 1).all()
    data = path.read_bytes()
    (tmp_path / "bad.pt").write_bytes(data[:100])
    with pytest.raises(CheckpointError):
        load_drqn(tmp_path / "bad.pt")


def test_shipped_checkpoint_plays_in_the_harness() -> None:
    from policy.baselines import make_policy

    cfg = GridConfig()
    r = evaluate(make_policy("drqn", cfg), cfg, 4, seed=3, progress=False)
    assert r.moves.shape == (4,) and (r.moves >= r.optimal).all()


def test_cut_episodes_are_not_terminal() -> None:
    rb = EpisodeReplay(2, np.random.default_rng(0))
    z = np.zeros((4, 3, 3, 3), np.uint8)
    rb.add(z, np.zeros((4, 3, 3), bool), np.zeros(4, int), np.zeros(4), terminal=False)
    _, _, _, _, d, m = rb.sample(1, 8)
    assert d.sum() == 0, "a cap is not an end state: no done flag"
    assert m[0].tolist() == [1, 1, 1, 0, 0, 0, 0, 0], "its last step has no successor frame: left out"
    rb.episodes.clear()
    rb.add(z, np.zeros((4, 3, 3), bool), np.zeros(4, int), np.zeros(4), terminal=True)
    _, _, _, _, d, m = rb.sample(1, 8)
    assert d[0, 3] == 1 and m[0, :4].all(), "found-everything ends the episode"


def test_distinct_frames_give_the_same_q_values() -> None:
    torch.manual_seed(0)
    net = Drqn(4, 84).eval()
    rng = np.random.default_rng(1)
    views = (rng.random((2, 6, 3, 3, 3)) < 0.2).astype(np.uint8)
    views[:, 3:] = views[:, :3]  # repeats, as in a real replay batch
    found = np.zeros((2, 6, 3, 3), bool)
    full = torch.from_numpy(drqn_view(views.reshape(-1, 3, 3, 3), found.reshape(-1, 3, 3))).reshape(2, 6, 3, 84, 84)
    learner = DrqnLearner(DrqnConfig(), GridConfig(), 0)
    fr, idx = learner.frames(views, found)
    assert len(fr) < 12
    with torch.no_grad():
        assert torch.equal(net(full)[0], net(fr, index=idx)[0])


def test_resume_gives_the_same_weights(tmp_path: Path) -> None:
    grid = GridConfig(width=5, height=5, n_targets=2)
    cfg = DrqnConfig(image=42, episodes=32, envs=8, warmup_steps=100, eps_anneal_steps=200, train_max_steps=30,
                     save_every=8)
    straight, _ = load_drqn(train_drqn(cfg, grid, tmp_path / "a", seed=4, progress=False))
    train_drqn(DrqnConfig(**{**cfg.__dict__, "episodes": 16}), grid, tmp_path / "b", seed=4, progress=False)
    resumed, doc = load_drqn(train_drqn(cfg, grid, tmp_path / "b", seed=4, progress=False, resume=True))
    assert doc["created_utc"] and doc["git_revision"]
    for k, v in straight.state_dict().items():
        assert torch.equal(v, resumed.state_dict()[k]), k
    with pytest.raises(CheckpointError, match="another run"):
        train_drqn(cfg, grid, tmp_path / "b", seed=5, progress=False, resume=True)
