"""searchnet with altitude levels and masked fields (issues 27, 28): a tiny DAgger from the
altitude planner and from the masked belief planner, the checkpoint's round trip, and the
decisions of the trained network only ever valid moves (never into a masked cell, never above
the top level, the batch-1 fast path the same as the torch forward)."""

from pathlib import Path

import numpy as np
import torch

from policy.base import observe
from policy.searchnet import SearchNet, SearchNetPolicy
from policy.searchnet.checkpoint import load_searchnet, read_searchnet, save_searchnet
from policy.searchnet.dagger import DaggerConfig, run_dagger
from policy.searchnet.fields import FieldSpec
from policy.searchnet.train import SearchTrainConfig
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

LEVELS3 = GridConfig(width=6, height=6, n_targets=2, levels=3)  # the measured detection table
FLAT = GridConfig(width=7, height=7, n_targets=2)


def _trained(grid: GridConfig, dc: DaggerConfig, level_planes: int) -> SearchNet:
    torch.manual_seed(0)
    tc = SearchTrainConfig(dagger=dc, ppo_updates=0, level_planes=level_planes, conv1=4, conv2=4, hidden=8)
    model = SearchNet(tc.net())
    data = run_dagger(model, grid, tc.dagger, None)
    assert data["valid"].shape[1] == tc.net().n_actions
    return model.eval()


def _fly(model: SearchNet, grid: GridConfig, n: int, seed: int, mask: np.ndarray | None = None,
         steps: int = 40) -> tuple[int, int]:
    """Drive n episodes with the network; every chosen action must be valid where it is chosen.
    Returns (decisions checked, climbs and descents chosen)."""
    ep = sample_episodes(grid, n, seed, mask)
    world = BatchGridWorld(ep, seed)
    pol = SearchNetPolicy(model, fast=n == 1)
    pol.reset(grid, n, seed)
    checked = vertical = 0
    for _ in range(steps):
        if world.done.all():
            break
        obs = observe(world)
        a = pol.act(obs)
        act = obs.active
        assert obs.valid[np.arange(n), a][act].all(), "an invalid move was chosen"
        checked += int(act.sum())
        vertical += int((a[act] >= 5).sum())
        world.step(a)
        assert (world.level <= grid.levels).all() and (world.level >= 1).all()
        if mask is not None:
            m = np.broadcast_to(mask, (n, grid.height, grid.width))
            assert m[np.arange(n), world.agent[:, 1], world.agent[:, 0]].all(), "entered a masked cell"
    return checked, vertical


def test_levels_dagger_round_trip_and_valid_decisions(tmp_path: Path) -> None:
    model = _trained(LEVELS3, DaggerConfig(iterations=2, episodes=2, chunks=1, epochs=1, beta0=0.5,
                                              max_steps_factor=0.5), 3)
    assert model.cfg.n_actions == 7 and model.cfg.level_planes == 3
    path = save_searchnet(tmp_path / "sn.pt", model, grid=LEVELS3.to_dict())
    assert read_searchnet(path)["model_config"]["level_planes"] == 3
    back, _ = load_searchnet(path)
    assert back.cfg == model.cfg
    for k, v in model.state_dict().items():
        torch.testing.assert_close(back.state_dict()[k], v, rtol=0, atol=0)
    checked, _ = _fly(back, LEVELS3, 3, seed=11, steps=25)
    assert checked > 20
    # the same network on one height (climb and descend masked: no level to go to)
    checked, vertical = _fly(back, FLAT, 3, seed=12, steps=20)
    assert checked > 10 and vertical == 0
    # batch 1: the fast forward (level planes in its buffer) decides as SearchNet's own
    ep = sample_episodes(LEVELS3, 1, 13)
    world = BatchGridWorld(ep, 13)
    fast, ref = SearchNetPolicy(back, fast=True), SearchNetPolicy(back, fast=False)
    fast.reset(LEVELS3, 1, 13)
    ref.reset(LEVELS3, 1, 13)
    for _ in range(5):
        obs = observe(world)
        zf, zr = fast.logits(obs), ref.logits(obs)
        ok = obs.valid[0]
        np.testing.assert_allclose(zf[0, ok], zr[0, ok], rtol=1e-4, atol=1e-4)
        world.step(zr.argmax(axis=1))


def test_masked_dagger_never_enters_a_masked_cell() -> None:
    dc = DaggerConfig(iterations=2, episodes=4, chunks=2, epochs=1, beta0=0.5,
                      fields=FieldSpec(classes=("L", "holes"), area=20))
    model = _trained(FLAT, dc, 0)
    assert model.cfg.n_actions == 5 and model.cfg.level_planes == 0
    grid, masks = dc.fields.draw(FLAT, 3, seed=5)
    checked, _ = _fly(model, grid, 3, seed=5, mask=masks)
    assert checked > 10
    # a fixed field (what `train --field FILE` gives) draws the same mask for every task
    fixed = FieldSpec.fixed(masks[0])
    g, m = fixed.draw(grid, 2, seed=99)
    assert g == grid and np.array_equal(m, masks[0])
