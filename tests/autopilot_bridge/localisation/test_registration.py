"""Found targets register the position again (Registration.register_known), against a real
vehicle over MAVLink: the autopilot's estimate (LOCAL_POSITION_NED) identifies a found cow when
it is seen again, and its known cell measures where the camera truly is."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from bridge_pad import blob_at, on_the_pad

from autopilot_bridge.detection.detector import Blob, px_per_m
from autopilot_bridge.detection.found import RECORD_P, lattice_p
from autopilot_bridge.localisation.edges import EdgeSighting, border_ne, half_footprint_m
from autopilot_bridge.localisation.registration import EDGE_REACH_MARGIN_M, KNOWN_SD_M, Registration
from sim.gridworld import cell_to_ned


def test_a_found_target_seen_again_registers_the_camera_on_its_cell() -> None:
    with on_the_pad(31) as pad:
        link, spec, estimator, intake, reg, t, cell = pad.link, pad.spec, pad.estimator, pad.intake, pad.reg, pad.t, pad.cell
        height = spec.camera_height()
        camera = cell_to_ned(cell)
        # found under the camera, 0.3 m north-east of the nadir, with the camera estimate agreeing
        # with the commanded cell and the camera well known: its cell is kept
        found = blob_at((0.3, 0.2), height)
        reg.found.remember(t, [found], camera, cell, np.eye(2) * 0.1)
        seen = reg.found.reading_at(t) + np.array([0.3, 0.2])
        assert reg.found.match(seen, t) == 0
        # read 1.4 m off: at once, a new cow on the next cell (the readings cannot drift apart
        # so far); two minutes later, the found one (the GPS bias drifts ~1 m in that time)
        assert reg.found.match(seen + np.array([1.4, 0.0]), t) is None
        assert reg.found.match(seen + np.array([1.4, 0.0]), t + 120.0) == 0
        assert reg.found.match(seen + np.array([2.0, -2.0]), t + 4.0) is None
        # the same cow again: where the camera truly is follows from its cell, whatever the GPS
        before = estimator.posterior(t)
        used, rest = reg.register_known(t, [found, blob_at((2.5, -2.4), height)])
        assert used == 1 and len(rest) == 1, "the found cow registers; the other blob is left for the lattice"
        after = estimator.posterior(t)
        z = cell_to_ned(cell) - np.array([0.3, 0.2])
        assert np.linalg.norm(after.mean_ned[:2] - z) < np.linalg.norm(before.mean_ned[:2] - z) + 1e-9
        assert np.trace(after.horizontal_cov) < np.trace(before.horizontal_cov)
        # fused at KNOWN_SD_M (repeat sightings of one cow err alike), not at the detector's 0.3 m
        prior = np.diag(before.horizontal_cov)
        assert np.all(np.diag(after.horizontal_cov) > 1.0 / (1.0 / prior + 1.0 / 0.3**2) * 1.2)
        np.testing.assert_allclose(np.diag(after.horizontal_cov), 1.0 / (1.0 / prior + 1.0 / KNOWN_SD_M**2), rtol=0.05)
        # found where the camera estimate disagreed with the commanded cell: no cell is kept,
        # so a re-sighting of it is no known cell's measurement (a cell recorded wrong locks
        # frames a cell off); it is left to the lattice odds, as any target
        reg2 = Registration(link, spec, estimator, intake)
        reg2.found.remember(t, [found], camera + np.array([0.0, 1.5]), cell, np.eye(2) * 0.1)
        used2, rest2 = reg2.register_known(t, [found])
        assert used2 == 0 and rest2 == [found]
        # found in the commanded cell but 0.8 m off its centre on both axes with the camera
        # known to 0.67 m: the neighbours are too likely (held-out seeds 30, 34), no cell kept
        reg3 = Registration(link, spec, estimator, intake)
        reg3.found.remember(t, [found], camera + np.array([0.5, 0.6]), cell, np.eye(2) * 0.45)
        assert lattice_p(np.array([0.8, 0.8]), np.full(2, 0.45 + found.sd_m**2)).max() < RECORD_P
        # near the believed cell's centre but the camera known to 0.84 m only: either neighbour
        # is likely (flight seed 6 recorded such a cow a row off: the far neighbour counts too)
        assert float(lattice_p(np.array(0.1), np.array(0.7 + found.sd_m**2))) < RECORD_P
        used3, rest3 = reg3.register_known(t, [found])
        assert used3 == 0 and rest3 == [found]


def test_a_blob_cut_by_the_frame_registers_only_across_the_cut() -> None:
    """A target cut by the frame's south edge runs on out of the frame by an unknown part of
    its length: its centre says where the camera is east-west (registered), not north-south."""
    with on_the_pad(32) as pad:
        estimator, reg, t, cell = pad.estimator, pad.reg, pad.t, pad.cell
        height = pad.spec.camera_height()
        # the camera known to be over its cell's centre, so the lattice odds are high
        for _ in range(3):
            estimator.observe_position(t, cell_to_ned(cell), 0.1)
        k = px_per_m(height)
        cut = Blob(row=2.0 * k, col=0.1 * k, pixels=120, cut=(False, True, False, False))
        whole = blob_at((-1.9, 0.1), height)
        for blob, moved in ((cut, (False, True)), (whole, (True, True))):
            before = np.diag(estimator.posterior(t).horizontal_cov).copy()
            used, _ = reg.register_targets(t, [blob], cell)
            after = np.diag(estimator.posterior(t).horizontal_cov)
            assert used == 1
            assert tuple(bool(v) for v in after < before - 1e-6) == moved, (before, after)


def test_a_found_target_cut_by_the_frame_registers_the_axis_along_the_cut() -> None:
    """A found cow seen again at the frame's south edge still says where the camera is east-
    west (its centre along the cut is as good as inside the frame: 0.14 m rms rendered), not
    north-south. Left out whole, a found cow's east offset went unused while the GPS bias
    drifted 0.6 m in 4 s (flight seed 69: 88 moves against 19 in the grid world)."""
    with on_the_pad(35) as pad:
        estimator, reg, t, cell = pad.estimator, pad.reg, pad.t, pad.cell
        height = pad.spec.camera_height()
        camera = cell_to_ned(cell)
        k = px_per_m(height)
        # seen 2.45 m south (its south end out of the frame), the cow of the cell south that
        # was found from here before (its cell kept: the camera known then)
        cut = Blob(row=2.1 * k, col=0.2 * k, pixels=90, cut=(False, True, False, False))
        south = cell + np.array([0, 1])
        reg.found.remember(t, [blob_at(cut.offset_ne(height), height)], camera + np.array([0.45, -0.2]), south,
                     np.eye(2) * 0.05)
        assert reg.found.match(reg.found.reading_at(t) + np.array(cut.offset_ne(height)), t) == 0
        before = np.diag(estimator.posterior(t).horizontal_cov).copy()
        used, rest = reg.register_known(t, [cut])
        after = np.diag(estimator.posterior(t).horizontal_cov)
        assert used == 1 and rest == []
        assert abs(after[0] - before[0]) < 1e-9, "north: across the cut, not registered"
        np.testing.assert_allclose(after[1], 1.0 / (1.0 / before[1] + 1.0 / KNOWN_SD_M**2), rtol=0.05)


def test_a_fix_stamped_before_a_fused_position_measurement_is_left_out() -> None:
    """A decision's position measurement moves the filter to the decision's time; a fix stamped
    just before it that was left for the next decision (half a fix period) cannot be fused
    after it: it is counted, not a crash (a lossy link's flight once ended on 'measurement time
    went backwards')."""
    with on_the_pad(33) as pad:
        ahead = pad.t + 0.5
        pad.estimator.observe_position(ahead, cell_to_ned(pad.cell), 0.1)
        pad.link.wait_for(lambda: pad.intake.last_gps_t > ahead + 0.3, 10, "fixes after the measurement")
        pad.intake.fuse_until(ahead + 0.5)
        assert pad.intake.fixes_late >= 1
        assert pad.estimator.time_s >= ahead


def test_the_launch_point_registers_the_bias_from_the_autopilots_estimate() -> None:
    """On its pad the vehicle stands on home: the fixes of the launch window and, at its end,
    the autopilot's own estimate (truth + bias, its white noise smoothed away) register the
    receiver's bias; 2 s of fixes alone average it to 0.19 m sd (flight seed 43: 0.5 m off on
    both axes). Checked against the simulated receiver's true bias."""
    with on_the_pad(36) as pad:
        pad.reg.register_launch()
        assert pad.reg.launch_registered
        truth = pad.sitl.gps.bias[:2].copy()
        assert np.abs(pad.estimator.bias_ned[:2] - truth).max() < 0.15, (pad.estimator.bias_ned, truth)
        assert pad.estimator.n_components == 1
        post = pad.estimator.posterior()
        assert np.abs(post.mean_ned[:2] - pad.intake.home_in_field()[:2]).max() < 0.1


def test_the_field_edge_registers_its_axis_and_an_unseen_border_picks_the_frame() -> None:
    """The field's west border seen 3 m west of the nadir says where the camera truly is east-
    west, whatever the lattice said (a posterior a cell off is doubted and moved, not averaged);
    the borders not in view weigh the lattice's hypotheses: the frame that would have had the
    east border in view loses."""
    with on_the_pad(34) as pad:
        estimator, reg, t, spec = pad.estimator, pad.reg, pad.t, pad.spec
        g, height = spec.grid, spec.camera_height()
        # the posterior sure of a frame a cell east of the truth
        truth_e = 2.0
        estimator.doubt_split(3.0, (1,))
        estimator.observe_position(t, np.array([truth_e + 2.0]), 0.2, (1,))
        west = EdgeSighting(axis=1, side=-1, offset_m=border_ne(1, -1, g.width, g.height) - truth_e, lines=40)
        assert reg.register_edges(t, [west]) == 1
        post = estimator.posterior(t)
        assert abs(post.mean_ned[1] - truth_e) < 0.25 and post.horizontal_cov[1, 1] < 0.25**2
        # two hypotheses a cell apart near the east border (x = 9.5 cells, 19 m): 16 m (cell 8)
        # would have it 3 m out, in view; 14 m (cell 7) 5 m out, beyond the frame's reach
        estimator.doubt_split(3.0, (1,))
        estimator.observe_position_mixture(t, 1, np.array([14.0, 16.0]), 0.2)
        _, means, _ = estimator.components(t)
        assert estimator.n_components >= 2 and means[:, 1].min() < 14.5 and means[:, 1].max() > 15.5
        assert 3.0 < half_footprint_m(height) - EDGE_REACH_MARGIN_M < 5.0
        before = estimator.weights.copy()
        reg.register_unseen_edges(t, [west], 100.0)  # a field with no visible edge: no evidence
        np.testing.assert_allclose(estimator.weights, before)
        fenced = Registration(pad.link, replace(spec, field_edge=True), estimator, pad.intake)
        fenced.register_unseen_edges(t, [west], 100.0)
        w = estimator.weights
        _, means, _ = estimator.components(t)
        assert w[means[:, 1] > 15.0].sum() < 0.05
        assert abs(estimator.posterior(t).mean_ned[1] - 14.0) < 0.3
