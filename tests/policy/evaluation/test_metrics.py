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
