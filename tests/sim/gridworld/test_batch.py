import numpy as np

from sim.gridworld import Action, BatchGridWorld, GridConfig, GridSearchEnv, sample_episodes


def _straight_line_world() -> BatchGridWorld:
    cfg = GridConfig(width=5, height=5, n_targets=2)
    ep = sample_episodes(cfg, 1, seed=0)
    agent = np.array([[0, 0]])
    targets = np.array([[[2, 0], [2, 2]]])
    return BatchGridWorld(type(ep)(cfg, agent, targets, None, 0), seed=0)


def test_moves_recoveries_and_termination() -> None:
    w = _straight_line_world()
    assert w.step(np.array([Action.R]))[0] == 0
    assert w.step(np.array([Action.R]))[0] == 1  # (2, 0)
    assert w.find_moves[0, 0] == 2
    w.step(np.array([Action.B]))
    w.step(np.array([Action.B]))
    assert w.done[0] and w.success[0] and w.t[0] == 4
    assert list(w.find_moves[0]) == [2, 4]
    w.step(np.array([Action.L]))  # done episodes ignore actions
    assert w.t[0] == 4 and tuple(w.agent[0]) == (2, 2)


def test_off_map_action_replaced_by_a_valid_move_and_counted() -> None:
    w = _straight_line_world()
    w.step(np.array([Action.F]))  # off the top edge from (0, 0)
    assert w.t[0] == 1 and w.replaced[0] == 1
    assert tuple(w.agent[0]) in {(1, 0), (0, 1)}


def test_time_limit_records_t_e_plus_one() -> None:
    cfg = GridConfig()
    w = BatchGridWorld(sample_episodes(cfg, 20, seed=1), seed=1)
    w.run(lambda w: np.zeros(w.n, dtype=np.int64))  # always 'f': stuck at the top row
    assert w.done.all()
    failed = ~w.success
    assert failed.any() and (w.t[failed] == cfg.t_e + 1).all()


def test_view_encoding_and_map_values() -> None:
    w = _straight_line_world()
    v, m = w.observe()
    assert v.shape == (1, 3, 3, 3) and v.dtype == np.uint8
    # agent at (0, 0): the top row and left column are off the map
    assert v[0, 1, 0].all() and v[0, 1, :, 0].all() and v[0, 1, 2, 2] == 0
    assert v[0, 2, 1, 1] == 1
    w.step(np.array([Action.R]))
    v, m = w.observe()
    assert v[0, 0, 1, 2] == 1, "target at (2, 0) appears right of the agent at (1, 0)"
    assert m[0, 0, 0, 1] == 10 and m[0, 0, 0, 0] == 1 and m.sum() == 11


def test_memory_map_marks_met_targets() -> None:
    cfg = GridConfig(width=5, height=5, n_targets=2, map_variant="memory")
    w = BatchGridWorld(
        type(sample_episodes(cfg, 1, 0))(cfg, np.array([[0, 0]]), np.array([[[1, 0], [4, 4]]]), None, 0)
    )
    w.step(np.array([Action.R]))
    w.step(np.array([Action.B]))
    _, m = w.observe()
    assert m[0, 0, 0, 1] == 5 and m[0, 0, 1, 1] == 10 and m[0, 0, 0, 0] == 1


def test_spatiotemporal_trail_decays() -> None:
    cfg = GridConfig(width=6, height=6, motion="random_walk", map_variant="spatiotemporal", n_targets=1)
    w = BatchGridWorld(sample_episodes(cfg, 8, seed=3), seed=3)
    start = w.agent.copy()
    for _ in range(4):
        w.step(np.full(w.n, Action.N))
    _, m = w.observe()
    assert m.shape == (8, 2, 6, 6)
    rows = np.arange(8)
    assert (m[rows, 0, start[:, 1], start[:, 0]] == 50).all(), "staying refreshes the trail"
    w.step(np.where(w.valid_actions()[:, Action.R], Action.R, Action.L))
    _, m = w.observe()
    left = m[rows, 0, start[:, 1], start[:, 0]]
    assert ((left == 49) | w.done).all()


def test_same_seed_same_run() -> None:
    cfg = GridConfig(motion="herd", distribution="equidistant", map_variant="spatiotemporal")
    out = []
    for _ in range(2):
        w = BatchGridWorld(sample_episodes(cfg, 64, seed=5), seed=5)
        rng = np.random.default_rng(0)
        w.run(lambda w, rng=rng: rng.integers(0, 5, w.n))
        out.append((w.t.copy(), w.find_moves.copy(), w.observe()[1]))
    assert all((a == b).all() for a, b in zip(out[0], out[1], strict=True))


def test_gymnasium_env_api() -> None:
    from gymnasium.utils.env_checker import check_env

    env = GridSearchEnv(GridConfig(), render_mode="ansi")
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=1)
    total, done = 0.0, False
    while not done:
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        total += r
        done = term or trunc
    assert info["found"] == total
    assert "A" in env.render()
