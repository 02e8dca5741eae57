from pathlib import Path

import numpy as np
import pytest
import torch

from policy.base import observe
from policy.nn import (
    CheckpointError,
    ModelConfig,
    NetworkPolicy,
    build_model,
    export_torchscript,
    load_model,
    load_torchscript,
    map_scale_for,
    normalise,
    save_checkpoint,
)
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


@pytest.mark.parametrize("model", ["dualstream", "ssn"])
@pytest.mark.parametrize("variant,actions", [("spatial", 4), ("memory", 4), ("spatiotemporal", 5)])
def test_small_network_shapes_for_every_map_variant(model: str, variant: str, actions: int) -> None:
    channels = 2 if variant == "spatiotemporal" else 1
    for view in [(3, 3, 3), (3, 50, 50)]:
        cfg = ModelConfig(model=model, view_shape=view, map_shape=(channels, 10, 10), n_actions=actions)
        net = build_model(cfg)
        v = torch.randint(0, 2, (7, *view), dtype=torch.uint8)
        m = torch.rand(7, channels, 10, 10) * 10
        p = net.probabilities(v, m)
        assert p.shape == (7, actions)
        assert torch.allclose(p.sum(1), torch.ones(7), atol=1e-5), "softmax output is normalised"


def test_paper_architecture_forward_pass_at_50x50_and_on_other_grid_sizes() -> None:
    net = build_model(ModelConfig(arch="paper", view_shape=(3, 50, 50), map_shape=(1, 10, 10)))
    assert net(torch.zeros(2, 3, 50, 50, dtype=torch.uint8), torch.zeros(2, 1, 10, 10)).shape == (2, 4)
    small = build_model(ModelConfig(map_shape=(1, 7, 13)))
    assert small(torch.zeros(1, 3, 3, 3), torch.zeros(1, 1, 7, 13)).shape == (1, 4)


def test_exported_model_gives_the_same_actions(tmp_path: Path) -> None:
    cfg = ModelConfig(map_shape=(2, 10, 10), n_actions=5, map_scale=50.0)
    net = build_model(cfg).eval()
    path = export_torchscript(net, cfg, tmp_path / "policy.ts")
    ts = load_torchscript(path)
    grid = GridConfig(motion="herd", distribution="equidistant", map_variant="spatiotemporal")
    world = BatchGridWorld(sample_episodes(grid, 64, 1), 1)
    eager, script = NetworkPolicy(net), NetworkPolicy(ts)
    for p in (eager, script):
        p.reset(grid, 64, 0)
    for _ in range(20):
        obs = observe(world)
        a, b = eager.act(obs), script.act(obs)
        assert (a == b).all()
        assert script.decide(obs.views[0], obs.maps[0]) == a[0], "single-step inference agrees"
        world.step(a)


def test_checkpoint_round_trip_and_clear_errors(tmp_path: Path) -> None:
    cfg = ModelConfig()
    net = build_model(cfg)
    path = save_checkpoint(tmp_path / "m.pt", net, cfg, seed=3, metrics={"val_acc": 0.5})
    loaded, doc = load_model(path)
    assert doc["seed"] == 3 and doc["git_revision"]
    for a, b in zip(net.state_dict().values(), loaded.state_dict().values(), strict=True):
        assert torch.equal(a, b)
    data = path.read_bytes()
    (tmp_path / "trunc.pt").write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match="trunc.pt"):
        load_model(tmp_path / "trunc.pt")
    (tmp_path / "junk.pt").write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(CheckpointError, match="junk.pt"):
        load_model(tmp_path / "junk.pt")
    with pytest.raises(CheckpointError, match="no such"):
        load_model(tmp_path / "absent.pt")
    with pytest.raises(CheckpointError, match="expected"):
        load_model(path, expect=ModelConfig(arch="paper"))
    torch.save({"hello": 1}, tmp_path / "foreign.pt")
    with pytest.raises(CheckpointError, match="not a uavsearch checkpoint"):
        load_model(tmp_path / "foreign.pt")


def test_normalisation_scales_follow_the_map_and_view_kinds() -> None:
    assert ModelConfig.for_data((3, 3, 3), (1, 10, 10), 4, rendered=False).map_scale == 10.0
    cfg = ModelConfig.for_data((3, 50, 50), (2, 8, 12), 5, rendered=True)
    assert (cfg.view_scale, cfg.map_scale) == (255.0, 50.0)
    v, m = normalise(torch.full((1, 3, 50, 50), 255, dtype=torch.uint8), torch.full((1, 2, 8, 12), 50.0),
                     torch.tensor(cfg.view_scale), torch.tensor(cfg.map_scale))
    assert float(v.max()) == 1.0 and float(m.max()) == 1.0
    with pytest.raises(ValueError, match="channels"):
        map_scale_for(3)


def test_shipped_checkpoint_loads_and_beats_the_naive_baseline() -> None:
    from policy.baselines import make_policy
    from policy.evaluation import evaluate
    from policy.loops import LoopGuard
    from policy.nn import load_shipped_policy, shipped_checkpoint

    assert shipped_checkpoint().exists()
    cfg = GridConfig()
    assert isinstance(load_shipped_policy(cfg), LoopGuard)
    ours = evaluate(make_policy("dualstream", cfg), cfg, 300, seed=11, progress=False).columns
    ns = evaluate(make_policy("ns", cfg), cfg, 300, seed=11, progress=False).columns
    assert ours["success_pct"] > 99.0
    assert ours["mean_moves"] < ns["mean_moves"]
    assert ours["loop_pct"] is not None, "runs under loop detection, as in the paper"


def test_paper_architecture_on_the_grid_view_with_the_spatiotemporal_map() -> None:
    cfg = ModelConfig(model="ssn", arch="paper", map_shape=(2, 10, 10), n_actions=5, map_scale=50.0)
    p = build_model(cfg).eval().probabilities(torch.zeros(3, 3, 3, 3, dtype=torch.uint8), torch.zeros(3, 2, 10, 10))
    assert p.shape == (3, 5) and torch.allclose(p.sum(1), torch.ones(3), atol=1e-5)


def test_weights_that_do_not_fit_the_declared_network_are_refused(tmp_path: Path) -> None:
    small = ModelConfig()
    other = build_model(ModelConfig(map_shape=(1, 8, 8)))  # same layers, other dense sizes
    path = save_checkpoint(tmp_path / "lying.pt", other, small)
    with pytest.raises(CheckpointError, match="do not fit"):
        load_model(path)
