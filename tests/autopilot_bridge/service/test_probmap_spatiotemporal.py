"""With a crisp position the companion's spatiotemporal map is the grid world's own (moving
targets' policies were trained on it); an uncertain position spreads it."""

import numpy as np

from autopilot_bridge.service.probmap import ProbabilisticVisitationMap
from sim.gridworld import BatchGridWorld, GridConfig, cell_to_ned, sample_episodes


def test_crisp_spatiotemporal_map_matches_the_grid_world() -> None:
    cfg = GridConfig(width=6, height=5, n_targets=2, motion="herd", map_variant="spatiotemporal")
    world = BatchGridWorld(sample_episodes(cfg, 1, 4), 4)
    pmap = ProbabilisticVisitationMap(cfg.width, cfg.height)
    crisp = np.eye(2) * 1e-6
    rng = np.random.default_rng(0)
    steps = 0
    for steps in range(25):  # noqa: B007
        cell = world.agent[0].copy()
        pmap.visit(cell_to_ned(cell), crisp)
        _, maps = world.observe()
        np.testing.assert_allclose(pmap.policy_map("spatiotemporal")[0], maps[0, 0], atol=1e-4)
        valid = np.flatnonzero(world.valid_actions()[0])
        if world.done[0]:
            break
        world.step(np.array([rng.choice(valid)]))
    assert steps >= 5 and pmap.policy_map("spatiotemporal").shape == (2, cfg.height, cfg.width)


def test_uncertain_position_spreads_the_trail() -> None:
    pmap = ProbabilisticVisitationMap(5, 5)
    pmap.visit(cell_to_ned(np.array([2, 2])), np.eye(2) * 1.0)
    trail = pmap.policy_map("spatiotemporal")[0]
    assert 0 < trail[2, 2] < 50 and trail[2, 3] > 0 and abs(trail.sum() - 50) < 1.0
    pmap.mark_target()
    assert pmap.policy_map("spatiotemporal")[1, 2, 2] == trail[2, 2]
