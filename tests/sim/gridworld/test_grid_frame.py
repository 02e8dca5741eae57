"""sim.gridworld.coords.GridFrame: the one cell <-> NED mapping at any heading and origin."""

import numpy as np
import pytest

from sim.gridworld import GridFrame, cell_to_ned, nearest_cell, ned_to_cell


def test_heading_zero_origin_zero_is_the_north_aligned_mapping_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    cells = np.concatenate([rng.integers(0, 30, size=(50, 2)), rng.uniform(-2, 30, size=(50, 2))])
    ne = rng.uniform(-60, 60, size=(100, 2))
    f = GridFrame()
    assert f.cell_to_ned(cells).tobytes() == cell_to_ned(cells).tobytes()
    assert f.ned_to_cell(ne).tobytes() == ned_to_cell(ne).tobytes()
    assert np.array_equal(f.nearest_cell(ne), nearest_cell(ne))
    assert f.rotate_to_grid(ne).tobytes() == ne.tobytes()


@pytest.mark.parametrize("heading", [0.0, 30.0, -120.0])
def test_cells_and_ned_round_trip_and_f_flies_along_the_heading(heading: float) -> None:
    f = GridFrame(heading, 2.0, (3.5, -8.25))
    rng = np.random.default_rng(1)
    cells = rng.uniform(-3, 25, size=(200, 2))
    np.testing.assert_allclose(f.ned_to_cell(f.cell_to_ned(cells)), cells, atol=1e-12)
    ne = rng.uniform(-50, 50, size=(200, 2))
    np.testing.assert_allclose(f.cell_to_ned(f.ned_to_cell(ne)), ne, atol=1e-12)
    np.testing.assert_allclose(f.grid_to_ned(f.ned_to_grid(ne)), ne, atol=1e-12)
    assert np.array_equal(f.nearest_cell(f.cell_to_ned(np.array([[4, 7], [0, 0]]))), [[4, 7], [0, 0]])
    h = np.radians(heading)
    o = f.cell_to_ned((0, 0))
    assert o.tolist() == [3.5, -8.25]
    np.testing.assert_allclose(f.cell_to_ned((0, -1)) - o, 2 * np.array([np.cos(h), np.sin(h)]), atol=1e-12)
    np.testing.assert_allclose(f.cell_to_ned((1, 0)) - o, 2 * np.array([-np.sin(h), np.cos(h)]), atol=1e-12)
    # the grid's own frame is today's mapping: a cell's (ahead, right) metres
    np.testing.assert_allclose(f.ned_to_grid(f.cell_to_ned(cells)), cell_to_ned(cells), atol=1e-12)


def test_bad_values_say_which() -> None:
    with pytest.raises(ValueError, match="heading"):
        GridFrame(float("nan"))
    with pytest.raises(ValueError, match="cell_m"):
        GridFrame(0.0, 0.0)
