"""Moving targets in the SITL keep the grid world's pace per decision: one grid step per
target_step_s of simulated time from the first arming, for the whole episode."""

import numpy as np

from autopilot_bridge.link.connection import VehicleLink
from sim.gridworld import GridConfig


def test_herd_moves_one_grid_step_per_decision_period_from_arming(sitl_factory) -> None:
    grid = GridConfig(motion="herd", map_variant="spatiotemporal")
    sitl = sitl_factory(physics="kinematic", speedup=20.0, grid=grid, target_step_s=2.0, gcs_link=False)
    paths = sitl.episode.paths[0]
    link = VehicleLink(f"udpin:127.0.0.1:{sitl.cfg.api_ports[1]}")
    try:
        link.wait_heartbeat()
        link.wait_for(lambda: link.telemetry.gps.get("fix_type", 0) >= 3, 20, "a GPS fix")
        np.testing.assert_array_equal(sitl.target_cells(), paths[0])  # still before arming
        link.arm()
        # the arming time is recorded on the simulation step after the ACK: wait for it
        link.wait_for(lambda: sitl._motion_t0 is not None, 10, "the SITL to record the arming time")
        t0 = sitl._motion_t0
        for k in (3, 7, 40, paths.shape[0] + 5):
            np.testing.assert_allclose(sitl.target_cells(t0 + 2.0 * k), paths[min(k, len(paths) - 1)])
        assert not np.array_equal(paths[0], paths[40]), "the herd does move over 40 decisions"
    finally:
        link.close()
