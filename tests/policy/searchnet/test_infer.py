"""The batch-1 decision path (policy.searchnet.infer.FastSearchNet) against SearchNet's torch
forward: the same logits within float32 rounding at every position of every field size, and
on real episodes with the shipped checkpoints the same actions at every step, loop guard
included (the flight's decision), and logits that agree within a tight tolerance."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from policy.base import observe
from policy.belief import BELIEF_CHANNELS
from policy.loops import LoopGuard
from policy.nn import shipped_checkpoint
from policy.searchnet import SearchNet, SearchNetConfig, SearchNetPolicy, load_searchnet_policy
from policy.searchnet.encode import egocentric_np
from policy.searchnet.infer import MASKED, FastSearchNet
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


def _reference(model: SearchNet, planes: np.ndarray, pos: np.ndarray, valid: np.ndarray) -> np.ndarray:
    mask = np.zeros((1, model.cfg.n_actions), bool)
    mask[:, : valid.shape[1]] = valid
    with torch.inference_mode():
        return model(torch.from_numpy(egocentric_np(planes, pos)), torch.from_numpy(mask)).numpy()


@pytest.mark.parametrize("size", [(10, 10), (20, 20), (6, 9), (3, 5), (2, 2)])
@pytest.mark.parametrize("local", [5, 3])
def test_fast_forward_equals_searchnet_at_every_position(size: tuple[int, int], local: int) -> None:
    h, w = size
    torch.manual_seed(h * w + local)
    model = SearchNet(SearchNetConfig(BELIEF_CHANNELS, local=local)).eval()
    with torch.no_grad():  # larger biases than the initialisation's, so every term matters
        for p in model.parameters():
            p.add_(torch.randn_like(p) * 0.1)
    fast = FastSearchNet(model)
    rng = np.random.default_rng(0)
    for y in range(h):
        for x in range(w):
            planes = rng.random((1, BELIEF_CHANNELS, h, w)).astype(np.float32)
            valid = rng.random((1, 4 + (x + y) % 2)) > 0.3  # static (4 moves) and moving (5)
            pos = np.array([[x, y]])
            want = _reference(model, planes, pos, valid)
            got = fast.logits(planes, pos, valid)
            np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)
            assert np.array_equal(got == MASKED, want == MASKED)


def test_fast_forward_reads_the_planes_in_place_and_checks_shapes() -> None:
    torch.manual_seed(0)
    model = SearchNet(SearchNetConfig(BELIEF_CHANNELS)).eval()
    fast = FastSearchNet(model)
    planes = np.random.default_rng(1).random((1, BELIEF_CHANNELS, 10, 10)).astype(np.float32)
    buf = fast.input_planes(10, 10)
    buf[:] = planes
    pos, valid = np.array([[0, 9]]), np.ones((1, 4), bool)
    np.testing.assert_allclose(fast.logits(buf, pos, valid), _reference(model, planes, pos, valid),
                               rtol=1e-5, atol=1e-5)
    with pytest.raises(ValueError, match="planes must be"):
        fast.logits(np.zeros((2, BELIEF_CHANNELS, 10, 10), np.float32), np.zeros((2, 2), int))


CASES = [
    ("searchnet_static_random", GridConfig()),
    ("searchnet_static_equidistant", GridConfig(distribution="equidistant")),
    ("searchnet_herd_equidistant", GridConfig(motion="herd", distribution="equidistant")),
    ("searchnet_static_random", GridConfig(width=20, height=20, n_targets=10)),
]


@pytest.mark.parametrize("name, cfg", CASES)
def test_fast_path_decides_like_the_reference_on_real_episodes(name: str, cfg: GridConfig) -> None:
    """Reference (fast=False) and fast path see the same observations; the reference drives.
    The flight's decision includes the loop guard for static targets: compared through it too."""
    ref = load_searchnet_policy(shipped_checkpoint(name), cfg, fast=False)
    new = load_searchnet_policy(shipped_checkpoint(name), cfg)
    decisions, worst = 0, 0.0
    seeds = 6 if cfg.width <= 10 else 2  # 20 x 20 episodes run ~200 moves
    for seed in range(seeds):
        ep = sample_episodes(cfg, 1, 50_000 + seed)
        world = BatchGridWorld(ep, seed)
        ref.reset(cfg, 1, seed)
        new.reset(cfg, 1, seed)
        assert new.fast is not None and ref.fast is None
        while not world.done.all():
            obs = observe(world)
            zr, zn = ref.logits(obs), new.logits(obs)
            assert np.array_equal(zr.argmax(1), zn.argmax(1)), (seed, int(world.t[0]))
            valid = zr > MASKED / 2
            assert np.array_equal(valid, zn > MASKED / 2)
            worst = max(worst, float(np.abs(zr - zn)[valid].max()))
            world.step(np.minimum(zr.argmax(1), cfg.n_actions - 1))
            decisions += 1
    assert worst < 1e-4, worst
    assert decisions > 60
    if not cfg.moving:  # the flight's whole decision: under the paper's loop guard
        guarded_ref, guarded_new = LoopGuard(ref), LoopGuard(new)
        for seed in range(seeds, seeds + (4 if cfg.width <= 10 else 1)):
            world = BatchGridWorld(sample_episodes(cfg, 1, 50_000 + seed), seed)
            guarded_ref.reset(cfg, 1, seed)
            guarded_new.reset(cfg, 1, seed)
            while not world.done.all():
                obs = observe(world)
                a = guarded_ref.act(obs)
                assert np.array_equal(a, guarded_new.act(obs))
                world.step(a)


def test_fast_net_follows_the_weights() -> None:
    """A model trained (changed in place) between resets gets a new fast forward; an unchanged
    one keeps its buffers."""
    torch.manual_seed(0)
    model = SearchNet(SearchNetConfig(BELIEF_CHANNELS))
    pol = SearchNetPolicy(model)
    cfg = GridConfig()
    pol.reset(cfg, 1, 0)
    first = pol.fast
    pol.reset(cfg, 1, 1)
    assert pol.fast is first
    with torch.no_grad():
        model.pi.bias.add_(1.0)
    pol.reset(cfg, 1, 2)
    assert pol.fast is not first
    obs = observe(BatchGridWorld(sample_episodes(cfg, 1, 0), 0))
    planes = np.random.default_rng(0).random((1, BELIEF_CHANNELS, 10, 10)).astype(np.float32)
    np.testing.assert_allclose(pol.fast.logits(planes, obs.positions, obs.valid),
                               _reference(model.eval(), planes, obs.positions, obs.valid), rtol=1e-5, atol=1e-5)
    pol.reset(cfg, 4, 0)
    assert pol.fast is None  # batches run SearchNet
