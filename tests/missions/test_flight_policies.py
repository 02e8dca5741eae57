"""Any registered policy flies, on any field size it can serve: the recurrent DRQN (whose wall
bumps leave it in place) and a frontier search over an 80 m x 80 m field (40 x 40 cells)."""

import json
from pathlib import Path

import pytest

from missions.flight import fly_search
from policy.baselines import register_policy, registry
from policy.baselines.frontier import FrontierPolicy
from sim.gridworld import GridConfig

pytestmark = pytest.mark.slow


def _cells(path: Path) -> list[list[int]]:
    return json.loads((path / "search_log.json").read_text())["cells"]


def test_the_drqn_flies(tmp_path: Path) -> None:
    r = fly_search(tmp_path, seed=5, speedup=12.0, instance=23, max_moves=8, policy="drqn")
    assert r["error"] is None and r["policy"] == "drqn", r["error"]
    assert r["moves"] >= 1 and r["frames"] == r["moves"] + 1
    c = _cells(tmp_path)
    steps = {abs(a[0] - b[0]) + abs(a[1] - b[1]) for a, b in zip(c, c[1:], strict=False)}
    assert steps <= {0, 1}, "one grid move per decision, or a wall bump in place"


def test_a_40_by_40_field_flies_for_a_bounded_number_of_moves(tmp_path: Path) -> None:
    grid = GridConfig(width=40, height=40, n_targets=5)
    r = fly_search(tmp_path, seed=1, speedup=12.0, grid=grid, instance=24, max_moves=6, policy="frontier")
    assert r["error"] is None, r["error"]
    assert r["moves"] == 6 or r["believed_found"] == 5
    assert r["outcome"]["exit_code"] in (0, 3) and r["outcome"]["touchdown"] is None, "it landed by itself"
    cells = _cells(tmp_path)
    assert all(0 <= x < 40 and 0 <= y < 40 for x, y in cells)


class _FailsMidFlight(FrontierPolicy):
    """A policy with a bug that shows on its 4th decision in flight."""

    name = "fails_mid_flight"

    def reset(self, cfg, n, seed, episodes=None) -> None:
        super().reset(cfg, n, seed, episodes)
        self.calls = 0

    def act(self, obs):
        self.calls += 1
        if self.calls == 4:
            raise RuntimeError("policy bug at decision 4")
        return super().act(obs)


def test_an_exception_in_the_policy_brings_the_vehicle_home_and_down(tmp_path: Path) -> None:
    register_policy("fails_mid_flight", lambda cfg=None, **_: _FailsMidFlight())
    try:
        r = fly_search(tmp_path, seed=2, speedup=12.0, instance=26, max_moves=20, policy="fails_mid_flight")
    finally:  # other tests list every registered policy
        registry._REGISTRY.pop("fails_mid_flight")
    assert r["error"] == "RuntimeError: policy bug at decision 4"
    td = r["outcome"]["touchdown"]
    assert r["outcome"]["exit_code"] == 1 and td["commanded"] == ["RTL"] and td["disarmed"], td
    assert len(_cells(tmp_path)) == 4, "the log holds the moves flown before the failure"


def test_a_kinematic_vehicle_has_a_camera_and_flies_the_search(tmp_path: Path) -> None:
    r = fly_search(tmp_path, seed=3, speedup=12.0, instance=27, max_moves=6, policy="lawnmower", physics="kinematic")
    assert r["error"] is None and r["frames"] == r["moves"] + 1 and r["frames_missing"] == 0, r


def test_a_herd_flies_with_the_spatiotemporal_map_and_is_scored_where_it_is(tmp_path: Path) -> None:
    grid = GridConfig(motion="herd", map_variant="spatiotemporal", n_targets=3)
    r = fly_search(tmp_path, seed=6, speedup=12.0, grid=grid, instance=28, max_moves=8, policy="frontier",
                   physics="kinematic")
    assert r["error"] is None and r["frames"] == r["moves"] + 1, r
    assert 0 <= r["truly_found"] <= 3 and r["believed_found"] <= r["truly_found"] + 1


def test_truly_met_counts_a_moving_target_only_where_it_is_at_the_time() -> None:
    import numpy as np

    from missions.flight import truly_met

    track = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    herd = np.array([[[1.0, 0.0], [5.0, 5.0]], [[2.0, 0.0], [5.0, 5.0]], [[1.0, 0.0], [2.2, 0.1]]])
    assert truly_met(track, herd) == [False, True], "passing over a cell the target has left does not count"
