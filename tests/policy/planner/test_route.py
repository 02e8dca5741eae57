"""The route of a static search with altitude levels (policy.planner.route): its looks, its
tour, and the planner flying it."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from policy.evaluation.altitude import run_rows
from policy.planner import BeliefPlanner
from policy.planner.altitude import AltitudeParams
from policy.planner.route import leg_costs, look_stops, open_tour, tile_edges, tour_cost
from sim.gridworld import DetectionTable, GridConfig


def test_tiles_and_looks_cover_what_is_left_from_the_lowest_level() -> None:
    assert tile_edges(20, 7).tolist() == [0, 7, 13, 20]
    assert tile_edges(10, 5).tolist() == [0, 5, 10]
    need = np.zeros((2, 14, 14), bool)
    need[0, 1:4, 2:5] = True  # a 3 x 3 leftover: one look from level 1 at its centre
    need[1, 7:14, 7:14] = True  # a whole 7 x 7 tile: level 3
    ex = ey = tile_edges(14, 7)
    stops, live = look_stops(need, ex, ey, top=3)
    assert live[0].tolist() == [True, False, False, False] and stops[0, 0].tolist() == [3, 2, 1]
    assert live[1].tolist() == [False, False, False, True] and stops[1, 3].tolist() == [10, 10, 3]
    stops, _ = look_stops(need, ex, ey, top=2)  # capped by the top level
    assert stops[1, 3, 2] == 2


def test_the_open_tour_is_short() -> None:
    rng = np.random.default_rng(3)
    ratios = []
    for _ in range(20):
        pts = np.concatenate([rng.integers(0, 20, (7, 2)), rng.integers(1, 4, (7, 1))], axis=1)
        cost = leg_costs(pts)
        order = open_tour(cost)
        assert sorted(order) == list(range(1, 7))
        best = min(tour_cost(cost, list(p)) for p in itertools.permutations(range(1, 7)))
        ratios.append(tour_cost(cost, order) / best)
    # a heuristic: mostly optimal, 1 % above on average (200 instances: 15 % above, at most 22 %)
    assert np.mean(ratios) <= 1.03 and max(ratios) <= 1.25
    # warm-started from a bad order it still finds the line
    line = np.array([[0, 0, 1], [3, 0, 1], [1, 0, 1], [2, 0, 1]])
    assert open_tour(leg_costs(line), warm=[1, 2, 3]) == [2, 3, 1]


def test_the_route_modes_find_every_static_target() -> None:
    with pytest.raises(ValueError, match="route"):
        AltitudeParams(route="lanes")
    cfg = GridConfig(width=14, height=14, n_targets=5, levels=3, detection=DetectionTable.perfect(3))
    for mode in ("full", "pickups"):
        pol = BeliefPlanner(altitude=AltitudeParams(route=mode))
        r = run_rows(pol, cfg, 8, 21)
        assert (r["found"] == 5).all() and r["moves_above_1"].sum() > 0
        again = run_rows(BeliefPlanner(altitude=AltitudeParams(route=mode)), cfg, 8, 21)
        assert np.array_equal(r["moves"], again["moves"])  # seeded: reproducible
