import numpy as np
import pytest

from policy.evaluation import recovery_rate, table1_columns


def test_recovery_rate_matches_the_reference_example() -> None:
    # finds after gaps 1, 1, 1, 1, 20 -> (1 + 1 + 1 + 1 + 0.05) / 5 = 0.81
    assert recovery_rate(np.array([[1, 2, 3, 4, 24]]))[0] == pytest.approx(0.81)
    # order of targets does not matter; nothing found gives 0; partial finds average found ones
    assert recovery_rate(np.array([[24, 3, 1, 4, 2]]))[0] == pytest.approx(0.81)
    assert recovery_rate(np.array([[-1, -1, -1]]))[0] == 0.0
    assert recovery_rate(np.array([[2, 6, -1]]))[0] == pytest.approx((1 / 2 + 1 / 4) / 2)


def test_columns_on_hand_made_episodes() -> None:
    moves = np.array([20, 25, 120, 301])
    optimal = np.array([20, 16, 20, 30])
    finds = np.array([[1, 2, 3, 4, 20], [5, 10, 15, 20, 25], [20, 40, 60, 80, 120], [1, -1, -1, -1, -1]])
    loops = np.array([0, 1, 3, 2])
    c = table1_columns(moves, optimal, finds, loops)
    assert c["loop_pct"] == 75.0
    assert c["multi_loop_pct"] == pytest.approx(200 / 3)  # 2 of the 3 looping episodes
    assert c["over_100_pct"] == 50.0
    assert c["optimal_pct"] == 25.0
    assert c["diff_lt_10_pct"] == 50.0 and c["diff_le_10_pct"] == 50.0
    assert c["timeout_pct"] == 25.0
    assert c["success_pct"] == 75.0
    assert c["mean_moves"] == pytest.approx(116.5)


def test_difference_readings_differ_at_exactly_ten() -> None:
    c = table1_columns(np.array([30]), np.array([20]), np.array([[30]]), None)
    assert c["diff_lt_10_pct"] == 0.0 and c["diff_le_10_pct"] == 100.0
    assert c["loop_pct"] is None


def test_bad_shapes() -> None:
    with pytest.raises(ValueError):
        table1_columns(np.array([1, 2]), np.array([1]), np.zeros((2, 1)), None)


def test_multi_loop_denominator_is_the_looping_episodes_only() -> None:
    n = 10
    moves, optimal, finds = np.full(n, 30), np.full(n, 20), np.full((n, 1), 30)
    loops = np.array([0, 0, 0, 0, 0, 0, 1, 2, 5, 1])  # 4 looped, 2 of them more than once
    c = table1_columns(moves, optimal, finds, loops)
    assert c["loop_pct"] == 40.0 and c["multi_loop_pct"] == 50.0  # not 2 / 10 = 20 %
    c = table1_columns(moves, optimal, finds, np.zeros(n, dtype=int))
    assert c["loop_pct"] == 0.0 and c["multi_loop_pct"] == 0.0


def test_failed_episodes_score_their_finds_and_the_plain_rates() -> None:
    moves = np.array([301, 10])
    finds = np.array([[50, 150, -1], [2, 4, 10]])
    c = table1_columns(moves, np.array([12, 8]), finds, None)
    rr0 = (1 / 50 + 1 / 100) / 2
    rr1 = (1 / 2 + 1 / 2 + 1 / 6) / 3
    assert c["recovery_rate_mean"] == pytest.approx((rr0 + rr1) / 2)
    assert c["recovery_rate_sd"] == pytest.approx(np.std([rr0, rr1]))
    assert c["targets_per_move"] == pytest.approx(5 / 311)
    assert c["mean_ratio_to_optimal"] == pytest.approx((301 / 12 + 10 / 8) / 2)
    assert c["timeout_pct"] == 50.0 and c["success_pct"] == 50.0 and c["over_100_pct"] == 50.0


def test_mismatched_inputs_are_refused() -> None:
    with pytest.raises(ValueError, match="find_moves"):
        table1_columns(np.array([1, 2]), np.array([1, 1]), np.zeros((3, 1)), None)
    with pytest.raises(ValueError, match="loops"):
        table1_columns(np.array([1, 2]), np.array([1, 1]), np.zeros((2, 1)), np.array([0]))
    with pytest.raises(ValueError, match="optimal"):
        table1_columns(np.array([1]), np.array([0]), np.zeros((1, 1)), None)
