"""The batched belief state against a per-episode, per-cell recomputation from the path.

Static targets: the belief is exact, so it must equal sets computed by walking each episode's
path (visited, seen, sighted-not-found, found count, prior-spread pool). Moving targets: a
plain-loop reference implementation of the same filter (every cell, every episode, one at a
time) must agree, and the truth must stay in the belief's support. GPS: the probabilistic
visited/seen maps against 1 - prod(1 - P) computed cell by cell.
"""

from __future__ import annotations

import numpy as np
import pytest

from policy.base import observe
from policy.belief import BELIEF_CHANNELS, PLANE_NAMES, BeliefState, estimate_prior, model_prior
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes


def _walk(cfg: GridConfig, n: int, seed: int, steps: int):
    """Random paths through real episodes: yields (world, obs) before each move."""
    ep = sample_episodes(cfg, n, seed)
    world = BatchGridWorld(ep, seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        yield world, observe(world)
        world.step(rng.integers(0, cfg.n_actions, n))


@pytest.mark.parametrize("dist", ["random", "gaussian"])
def test_static_belief_equals_recomputation_from_path(dist):
    cfg = GridConfig(distribution=dist, width=7, height=6, n_targets=4)
    prior = model_prior(cfg, samples=2000)
    n = 40
    b = BeliefState(cfg, n, prior)
    path: list[np.ndarray] = []
    for world, obs in _walk(cfg, n, seed=3, steps=35):
        b.update(obs)
        path.append(world.agent.copy())
        tg = world.targets()
        for i in range(n):
            visited = np.zeros((cfg.height, cfg.width), bool)
            seen = np.zeros_like(visited)
            for x, y in (p[i] for p in path):
                visited[y, x] = True
                seen[max(y - 1, 0): y + 2, max(x - 1, 0): x + 2] = True
            cells = {(int(x), int(y)) for x, y in tg[i]}
            found = sum(visited[y, x] for x, y in cells)
            sighted = np.zeros(visited.shape)
            for x, y in cells:
                if seen[y, x] and not visited[y, x]:
                    sighted[y, x] = 1.0
            pool = prior * ~seen
            left = cfg.n_targets - found - sighted.sum()
            expect = sighted + (pool / pool.sum() * left if pool.sum() > 0 else 0.0)
            assert np.array_equal(b.visited[i] > 0.5, visited) and set(np.unique(b.visited[i])) <= {0.0, 1.0}
            assert np.array_equal(b.seen[i] > 0.5, seen) and set(np.unique(b.seen[i])) <= {0.0, 1.0}
            assert b.n_found[i] == found == world.found[i].sum()
            np.testing.assert_allclose(b.target[i], expect, atol=1e-5)
            assert b.unsighted[i] == pytest.approx(left, abs=1e-5)


def _shift(a, dy, dx):
    h, w = a.shape
    out = np.zeros_like(a)
    for y in range(h):
        for x in range(w):
            if 0 <= y - dy < h and 0 <= x - dx < w:
                out[y, x] = a[y - dy, x - dx]
    return out


def _kernel_loops(cfg: GridConfig, a: np.ndarray) -> np.ndarray:
    """The motion model, written cell by cell: where a target at (x, y) can be one move later."""
    h, w = a.shape
    out = np.zeros_like(a, dtype=np.float64)
    for y in range(h):
        for x in range(w):
            nbs = [(x + dx, y + dy) for dx, dy in ((0, -1), (0, 1), (-1, 0), (1, 0))
                   if 0 <= x + dx < w and 0 <= y + dy < h]
            if cfg.motion == "random_walk":
                stay = ((4 - len(nbs)) / 4) ** 8 + 1e-3
                move = (1 - stay) / len(nbs)
            else:
                stay = cfg.herd_deviation / 3 + (1 - cfg.herd_deviation / 3) / 4 * (4 - len(nbs))
                move = (1 - cfg.herd_deviation / 3) / 4
            out[y, x] += a[y, x] * stay
            for nx, ny in nbs:
                out[ny, nx] += a[y, x] * move
    return out


def _reference_moving(cfg: GridConfig, views, positions, ts, active, recoveries):
    """The moving-target filter for one episode, in plain loops. recoveries: the map's
    recoveries value at the agent's cell per step (trail_value in the step of a find)."""
    h, w, r = cfg.height, cfg.width, cfg.n_targets
    u = np.full((h, w), r / (h * w))
    f = np.zeros((h, w))
    n_found = 0.0
    last = None
    for view, pos, t, act, rec in zip(views, positions, ts, active, recoveries, strict=True):
        if last is not None:
            for s in range(last, t):
                if s % cfg.target_period == 0:
                    u, f = _kernel_loops(cfg, u), _kernel_loops(cfg, f)
        last = t
        shown = {}
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                x, y = pos[0] + dx, pos[1] + dy
                if 0 <= x < w and 0 <= y < h:
                    shown[(x, y)] = view[0, dy + 1, dx + 1] > 0
        det_u, det_f = np.zeros((h, w)), np.zeros((h, w))
        newly = 0.0
        for (x, y), has in shown.items():
            tot = u[y, x] + f[y, x]
            ru = u[y, x] / tot if tot > 1e-9 else 1.0
            if has and (x, y) == tuple(pos):
                det_f[y, x] = 1.0
                newly += ru
            elif has:
                det_u[y, x], det_f[y, x] = ru, 1 - ru
        newly = 1.0 if rec >= cfg.trail_value - 0.5 else 0.0  # the map says when a find happened
        n_found = min(n_found + newly, r - 1 if act else r)
        for src, dst, total in ((det_u, det_f, r - n_found), (det_f, det_u, n_found)):
            if src.sum() > total + 1e-6:
                moved = src * (1 - total / src.sum())
                src -= moved
                dst += moved
        for pop, total, det in ((u, r - n_found, det_u), (f, n_found, det_f)):
            rest = pop.copy()
            for (x, y) in shown:
                rest[y, x] = 0.0
            want = max(total - det.sum(), 1e-3 * total)
            have = rest.sum()
            pop[:] = (rest * (want / have) if have > 1e-9 else rest) + det
    return u, f, n_found


@pytest.mark.parametrize("motion", ["random_walk", "herd"])
def test_moving_belief_equals_loop_reference_and_holds_the_truth(motion):
    dist = "equidistant" if motion == "herd" else "random"
    cfg = GridConfig(distribution=dist, motion=motion, width=8, height=7, n_targets=4,
                     map_variant="spatiotemporal")
    n = 12
    b = BeliefState(cfg, n)
    record = []
    for world, obs in _walk(cfg, n, seed=5, steps=40):
        b.update(obs)
        record.append(obs)
        tg = world.targets()
        live = ~world.found & ~world.done[:, None]
        held = b.target[np.arange(n)[:, None], tg[..., 1], tg[..., 0]] > 0
        assert not (live & ~held).any(), "an unfound target stands where the belief says none can be"
        # the known cardinality, up to the 1e-3 leak kept outside a view that seems to hold all
        np.testing.assert_allclose(b.target.sum(axis=(1, 2)), b.remaining, atol=2e-3 * cfg.n_targets)
    for i in range(n):
        u, f, nf = _reference_moving(cfg, [o.views[i] for o in record], [o.positions[i] for o in record],
                                     [int(o.t[i]) for o in record], [bool(o.active[i]) for o in record],
                                     [o.maps[i, 1, o.positions[i, 1], o.positions[i, 0]] for o in record])
        assert nf == world.found[i].sum()  # the map's recoveries channel makes the count exact
        np.testing.assert_allclose(b.target[i], u, atol=2e-4)
        np.testing.assert_allclose(b.found[i], f, atol=2e-4)
        assert b.n_found[i] == pytest.approx(nf, abs=1e-5)


def test_gps_probabilistic_maps_against_cellwise_products():
    cfg = GridConfig(width=6, height=5, n_targets=3)
    n = 6
    rng = np.random.default_rng(11)
    b = BeliefState(cfg, n, view_evidence=False)  # the reference conditions on the off-map pattern only
    exact = BeliefState(cfg, n)
    ps = []
    for _world, obs in _walk(cfg, n, seed=7, steps=12):
        p = rng.random((n, cfg.height, cfg.width)).astype(np.float32) ** 6
        p[np.arange(n), obs.positions[:, 1], obs.positions[:, 0]] += 1.0  # the truth is likely
        p /= p.sum(axis=(1, 2), keepdims=True)
        noisy = type(obs)(**{**obs.__dict__, "position_prob": p})
        b.update(noisy)
        exact.update(obs)
        # the reference conditions on the view's off-map pattern, cell by cell
        q = p.copy()
        for i in range(n):
            off = obs.views[i, 1]
            for y in range(cfg.height):
                for x in range(cfg.width):
                    pat = [[not (0 <= y + dy < cfg.height and 0 <= x + dx < cfg.width) for dx in (-1, 0, 1)]
                           for dy in (-1, 0, 1)]
                    if not np.array_equal(np.array(pat), off.astype(bool)):
                        q[i, y, x] = 0.0
            q[i] /= q[i].sum()
        ps.append(q)
        # the true cell always agrees with the view, so conditioning keeps it
        assert (q[np.arange(n), obs.positions[:, 1], obs.positions[:, 0]] > 0).all()
    for i in range(n):
        vis = 1 - np.prod([1 - q[i] for q in ps], axis=0)
        inview = [sum(_shift(q[i], dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)) for q in ps]
        seen = 1 - np.prod([1 - np.minimum(v, 1) for v in inview], axis=0)
        np.testing.assert_allclose(b.visited[i], vis, atol=1e-5)
        np.testing.assert_allclose(b.seen[i], seen, atol=1e-5)
    # uncertainty only spreads belief: every cell the exact belief has seen is partly seen
    assert (b.seen[exact.seen > 0] > 0).all()
    np.testing.assert_allclose(b.target.sum(axis=(1, 2)), cfg.n_targets - b.n_found, rtol=1e-4)


def test_one_hot_position_prob_is_the_exact_belief():
    cfg = GridConfig(width=7, height=7, n_targets=3)
    n = 10
    a, c = BeliefState(cfg, n), BeliefState(cfg, n)
    for _world, obs in _walk(cfg, n, seed=2, steps=20):
        p = np.zeros((n, 7, 7), np.float32)
        p[np.arange(n), obs.positions[:, 1], obs.positions[:, 0]] = 1
        a.update(obs)
        c.update(type(obs)(**{**obs.__dict__, "position_prob": p}))
    for name in ("visited", "seen", "target", "found", "n_found"):
        np.testing.assert_allclose(getattr(a, name), getattr(c, name), atol=1e-6)


def test_planes_and_bad_inputs():
    cfg = GridConfig()
    b = BeliefState(cfg, 3)
    obs = next(_walk(cfg, 3, seed=0, steps=1))[1]
    b.update(obs)
    pl = b.planes()
    assert pl.shape == (3, BELIEF_CHANNELS, 10, 10) == (3, len(PLANE_NAMES), 10, 10)
    assert pl.dtype == np.float32
    assert (pl[np.arange(3), PLANE_NAMES.index("agent"), obs.positions[:, 1], obs.positions[:, 0]] == 1).all()
    with pytest.raises(ValueError, match="prior must have shape"):
        BeliefState(cfg, 3, np.ones((4, 4)))
    with pytest.raises(ValueError, match="non-negative"):
        BeliefState(cfg, 3, -np.ones((10, 10)))


def test_estimate_prior_from_episodes_and_dataset(tmp_path):
    from policy.data import synthesize

    cfg = GridConfig(distribution="gaussian")
    ep = sample_episodes(cfg, 3000, 1)
    prior = estimate_prior(ep, cfg)
    assert prior.shape == (10, 10) and prior.sum() == pytest.approx(1.0)
    y, x = np.unravel_index(prior.argmax(), prior.shape)
    assert abs(x - 3) <= 1 and abs(y - 5) <= 1  # the gaussian's mean (3, 5)
    synthesize(cfg, 300, 4, tmp_path / "ds")
    from_data = estimate_prior(tmp_path / "ds", cfg)
    # the dataset's oracle paths recover the same placement: most mass within 2 cells of (3, 5)
    yy, xx = np.mgrid[0:10, 0:10]
    near = (np.abs(xx - 3) <= 2) & (np.abs(yy - 5) <= 2)
    assert from_data[near].sum() > 0.75
    with pytest.raises(FileNotFoundError):
        estimate_prior(tmp_path / "missing", cfg)


def test_pair_correlation_finds_the_lattice_and_sharpens_the_pool():
    from policy.belief import estimate_pair

    eq = GridConfig(distribution="equidistant")
    g = estimate_pair(sample_episodes(eq, 4000, 2), eq)
    c = 9  # offset (0, 0) sits at [h - 1, w - 1]
    assert g[c, c + 2] > 3 and g[c + 2, c] > 3  # spacing 2 along x and y
    assert g[c, c + 1] < 0.2 and g[c + 1, c + 1] < 0.2  # never at odd offsets
    rnd = estimate_pair(sample_episodes(GridConfig(), 4000, 2), GridConfig())
    assert np.median(np.abs(rnd - 1)) < 0.1  # independent placement: ~1
    # one sighted target: the unseen density now prefers the lattice's cells around it
    b = BeliefState(eq, 1, pair=g)
    b._sighted[0, 4, 4] = 1.0
    pool = b._pool()[0]
    assert pool[4, 6] > 3 * pool[4, 7] and pool[6, 4] > 3 * pool[5, 4]
