import numpy as np

from autopilot_bridge import cell_fractions, frame_to_view
from sim.vehicle import ViewRenderer, WorldState


def test_rendered_cows_become_the_grid_view() -> None:
    r = ViewRenderer(10, 10, 3, image=50, seed=4)
    try:
        targets = np.array([[5.0, 5.0], [6.0, 4.0], [0.0, 0.0]])  # below, north-east, far away
        frame = r.render_view(WorldState(10, 10, targets), np.array([5, 5]))
        frac = cell_fractions(frame)
        assert frac[1, 1] > 0.2 and frac[0, 2] > 0.1
        view = frame_to_view(frame, np.array([5, 5]), 10, 10)
        assert view[0].tolist() == [[0, 0, 1], [0, 1, 0], [0, 0, 0]]
        corner = frame_to_view(r.render_view(WorldState(10, 10, targets), np.array([0, 0])), np.array([0, 0]), 10, 10)
        assert corner[0, 1, 1] == 1 and corner[1, 0].all() and corner[1][:, 0].all()
    finally:
        r.close()
