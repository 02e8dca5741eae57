"""BatchGridWorld's direct observations (issue 13) equal the reference functions in
observations.py and actions.py at every step, for every map variant, static and moving."""

import numpy as np
import pytest

from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes
from sim.gridworld.actions import valid_mask
from sim.gridworld.observations import spatial_map, target_occupancy, views


@pytest.mark.parametrize("motion,dist,variant", [
    ("static", "random", "spatial"), ("static", "equidistant", "memory"),
    ("herd", "equidistant", "spatiotemporal"), ("random_walk", "random", "memory"),
])
def test_observations_equal_the_reference_functions(motion: str, dist: str, variant: str) -> None:
    cfg = GridConfig(width=8, height=6, motion=motion, distribution=dist, map_variant=variant)
    world = BatchGridWorld(sample_episodes(cfg, 300, 5), 5)
    rng = np.random.default_rng(1)
    found_any = False
    while not world.done.all():
        v, m = world.observe()
        occ = target_occupancy(world.targets(), cfg.width, cfg.height)
        np.testing.assert_array_equal(v, views(world.agent, occ))
        if variant != "spatiotemporal":
            ref = spatial_map(world.agent, world.visited, world.met if variant == "memory" else None)
            np.testing.assert_array_equal(m, ref)
        np.testing.assert_array_equal(world.valid_actions(), valid_mask(world.agent, cfg.width, cfg.height,
                                                                        cfg.n_actions))
        world.step(rng.integers(0, cfg.n_actions, world.n))
        found_any |= bool(world.found.any())
    assert found_any and world.success.any() and not world.success.all()
