import numpy as np
import pytest

from autopilot_bridge import ProbabilisticVisitationMap, cell_probabilities
from sim.gridworld import BatchGridWorld, GridConfig, cell_to_ned, sample_episodes


def test_mass_sums_to_one_inside_and_peaks_at_the_mean() -> None:
    ne = cell_to_ned((4, 6))
    p = cell_probabilities(ne, np.eye(2) * 0.8**2, 10, 10)
    assert p.shape == (10, 10)
    assert abs(p.sum() - 1.0) < 1e-6
    assert np.unravel_index(p.argmax(), p.shape) == (6, 4)


def test_correlated_covariance_matches_the_axis_aligned_path() -> None:
    ne = cell_to_ned((5.2, 4.7))
    a = cell_probabilities(ne, np.diag([0.9, 0.5]), 10, 10)
    b = cell_probabilities(ne, np.array([[0.9, 1e-9], [1e-9, 0.5]]) + np.diag([0, 0]), 10, 10)
    c = cell_probabilities(ne, np.array([[0.9, 0.3], [0.3, 0.5]]), 10, 10)
    assert np.allclose(a, b)
    assert abs(c.sum() - 1.0) < 2e-3
    with pytest.raises(ValueError):
        cell_probabilities(ne, np.array([[1.0, 2.0], [2.0, 1.0]]), 10, 10)


def test_certain_positions_reproduce_the_crisp_map() -> None:
    cfg = GridConfig(map_variant="spatial")
    world = BatchGridWorld(sample_episodes(cfg, 1, seed=2), seed=2)
    pmap = ProbabilisticVisitationMap(10, 10)
    rng = np.random.default_rng(0)
    pmap.visit(cell_to_ned(world.agent[0]), np.eye(2) * 1e-6)
    for _ in range(30):
        world.step(rng.integers(0, 4, 1))
        pmap.visit(cell_to_ned(world.agent[0]), np.eye(2) * 1e-6)
    _, crisp = world.observe()
    assert np.allclose(pmap.expected_map(), crisp[0], atol=1e-6)
    assert pmap.most_likely_cell() == tuple(world.agent[0])


def test_uncertain_visits_are_soft() -> None:
    pmap = ProbabilisticVisitationMap(10, 10)
    pmap.visit(cell_to_ned((5, 5)), np.eye(2) * 1.5**2)
    m = pmap.expected_map(memory=True)[0]
    assert 0 < pmap.visited[5, 4] < 1 and 0 < pmap.current[5, 4] < pmap.current[5, 5] < 1
    assert 0 < m[5, 4] < m[5, 5] < 10
    pmap.mark_target()
    assert pmap.expected_map(memory=True)[0, 5, 4] > m[5, 4]


def test_a_visit_spread_over_a_gaussian_sum_is_the_weighed_visits() -> None:
    """visit_cells takes P(in cell) from any posterior (the estimator's Gaussian sum: one
    component per lattice hypothesis); bad input names what is wrong."""
    a, b = cell_to_ned((5, 5)), cell_to_ned((6, 5))
    p = 0.7 * cell_probabilities(a, np.eye(2) * 0.09, 10, 10) + 0.3 * cell_probabilities(b, np.eye(2) * 0.09, 10, 10)
    pmap = ProbabilisticVisitationMap(10, 10)
    pmap.visit_cells(p)
    assert pmap.current[5, 5] == pytest.approx(0.7, abs=0.01) and pmap.current[5, 6] == pytest.approx(0.3, abs=0.01)
    assert pmap.most_likely_cell() == (5, 5)
    with pytest.raises(ValueError, match=r"\(10, 10\)"):
        pmap.visit_cells(np.ones((9, 10)) / 90)
    with pytest.raises(ValueError, match="sum 2"):
        pmap.visit_cells(np.ones((10, 10)) / 50)


def test_a_thin_posterior_across_a_slanted_line_keeps_its_mass() -> None:
    """A polygon edge's registration leaves the posterior a few centimetres thin across a
    slanted line: its mass per cell still sums to one (it summed to 1.03 on a coarse sub-grid,
    farm flight seed 3), and agrees with the same Gaussian a little wider."""
    n = np.array([np.cos(0.5), np.sin(0.5)])
    a = np.array([-n[1], n[0]])
    mean = np.array([-20.3, 11.7])
    for sd in (0.08, 0.05, 0.02, 0.005):
        p = cell_probabilities(mean, np.outer(n, n) * sd**2 + np.outer(a, a) * 0.5**2, 26, 26)
        assert p.min() >= 0 and p.sum() == pytest.approx(1.0, abs=2e-3), sd
    thin = cell_probabilities(mean, np.outer(n, n) * 0.03**2 + np.outer(a, a) * 0.5**2, 26, 26)
    wider = cell_probabilities(mean, np.outer(n, n) * 0.06**2 + np.outer(a, a) * 0.5**2, 26, 26)
    assert np.abs(thin - wider).max() < 0.03
