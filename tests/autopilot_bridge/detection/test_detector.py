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


def test_a_target_straddling_cells_lights_the_one_cell_its_centre_is_in() -> None:
    """The camera truly off its cell's centre by the GPS bias (0.7 m, 0.8 m): the window
    detector lit 2-3 windows per cow; the blob centroid puts each cow in exactly one cell, and
    the offsets it measures (GPS-free) are within the calibration's error of the truth."""
    from autopilot_bridge.detection.detector import find_blobs
    from autopilot_bridge.detection.view import blobs_to_view
    from sim.gridworld import cell_to_ned

    r = ViewRenderer(10, 10, 3, image=50, seed=2)
    try:
        targets = np.array([[5.0, 5.0], [6.0, 4.0], [4.0, 6.0]])  # below, north-east, south-west
        camera = np.array([5.0 + 0.4, 5.0 - 0.35])  # cells (x, y): 0.8 m east, 0.7 m north
        r.field.set_targets(targets)
        from sim.vehicle.field import cell_to_enu

        eye = cell_to_enu(camera, 2.0)
        eye[2] = 3.44
        blobs = find_blobs(r.camera.render_enu(eye))
        assert len(blobs) == 3
        cam_ne = cell_to_ned(camera)
        true_off = sorted(map(tuple, np.round(cell_to_ned(targets) - cam_ne, 2)))
        seen_off = sorted(b.offset_ne(3.44) for b in blobs)
        assert np.abs(np.array(seen_off) - np.array(true_off)).max() < 0.45, (seen_off, true_off)
        # the camera believed where it truly is: one slot per cow, none doubled
        view = blobs_to_view(blobs, cam_ne, 3.44, np.array([5, 5]), 10, 10)
        assert view[0].tolist() == [[0, 0, 1], [0, 1, 0], [1, 0, 0]]
        # believed 1.2 m east of the truth (a bias not registered): every cow one cell west
        shifted = blobs_to_view(blobs, cam_ne + np.array([0.0, 1.2]), 3.44, np.array([5, 5]), 10, 10)
        assert shifted[0].sum() == 2 and shifted[0, 0, 2] == 0
    finally:
        r.close()


def test_the_near_end_of_a_target_two_cells_away_is_not_a_neighbour() -> None:
    """A cow two cells north shows its near end at the frame's top edge; read as a neighbour,
    the planner stepped back and forth chasing it (the demo's moves 29-40)."""
    from autopilot_bridge.detection.detector import find_blobs
    from autopilot_bridge.detection.view import blobs_to_view
    from sim.gridworld import cell_to_ned

    r = ViewRenderer(10, 10, 1, image=50, seed=3)
    try:
        seen_far = 0
        for heading in np.linspace(-np.pi, np.pi, 8, endpoint=False):
            r.field.set_targets(np.array([[5.0, 3.0]]), np.array([heading]))
            blobs = find_blobs(r.render_view(WorldState(10, 10, np.array([[5.0, 3.0]])), np.array([5, 5])))
            seen_far += len(blobs)
            assert all(b.beyond_view(3.44) for b in blobs), [(b.row, b.col, b.inner_px) for b in blobs]
            view = blobs_to_view(blobs, cell_to_ned(np.array([5.0, 5.0])), 3.44, np.array([5, 5]), 10, 10)
            assert not view[0].any()
        assert seen_far >= 2  # its near end does show in some headings
        r.field.set_targets(np.array([[5.0, 4.0]]), np.array([0.0]))  # a neighbour is kept
        blobs = find_blobs(r.render_view(WorldState(10, 10, np.array([[5.0, 4.0]])), np.array([5, 5])))
        assert len(blobs) == 1 and not blobs[0].beyond_view(3.44)
    finally:
        r.close()


def test_two_cows_touching_head_to_rump_across_a_cell_border_are_two_targets() -> None:
    """A cow is 1.75 m long head to tail on a 2 m lattice and its back is magnified 1.4x: one
    heading into the next cell touches its neighbour in the frame. Read as one blob (one
    centroid 1.4 m out), the cow below was never found (flight seed 11: 2.7x the grid world's
    moves) or was found twice."""
    from autopilot_bridge.detection.detector import find_blobs
    from sim.gridworld import cell_to_ned
    from sim.vehicle.field import cell_to_enu

    targets = np.array([[5.0, 5.0], [6.0, 5.0]])
    # different coats (brown, white): head to head (the heads overlap by 0.1 m) or head to
    # rump (one coat: test_two_touching_cows_of_one_coat_are_two_targets)
    for seed, all_headings in ((0, ((0.0, np.pi), (0.0, 0.0))),):
        r = ViewRenderer(10, 10, 2, image=50, seed=seed)
        try:
            for headings in all_headings:  # the first heads east, into the second
                r.field.set_targets(targets, np.array(headings))
                for camera in (np.array([5.0, 5.0]), np.array([5.1, 4.9])):
                    eye = cell_to_enu(camera, 2.0)
                    eye[2] = 3.44
                    blobs = find_blobs(r.camera.render_enu(eye))
                    seen = sorted((b.offset_ne(3.44) for b in blobs), key=lambda v: v[1])  # west to east
                    true = sorted(map(tuple, cell_to_ned(targets) - cell_to_ned(camera)), key=lambda v: v[1])
                    assert len(blobs) == 2, (seed, r.field.coats, headings, seen)
                    assert np.abs(np.array(seen) - np.array(true)).max() < 0.5, (seen, true)
        finally:
            r.close()


def test_two_touching_cows_of_one_coat_are_two_targets() -> None:
    """Neither the erosion nor the coats part two cows of one coat that touch: the blob's
    length does (`_split_long`). Read as one blob centred between them (0.55-0.94 m off each),
    it registered the frame a row off and the second cow was hunted for 100 moves (flight
    seed 62)."""
    from autopilot_bridge.detection.detector import find_blobs
    from sim.gridworld import cell_to_ned
    from sim.vehicle.field import cell_to_enu

    for seed in (3, 5):  # renderers whose two cows share a coat (brown, black)
        r = ViewRenderer(10, 10, 2, image=50, seed=seed)
        try:
            assert r.field.coats[0] == r.field.coats[1]
            for targets, headings in (([[5.0, 5.0], [6.0, 5.0]], (0.0, 0.0)),  # head to rump, east
                                      ([[5.0, 5.0], [6.0, 5.0]], (0.0, np.pi)),  # head to head
                                      ([[5.0, 5.0], [5.0, 4.0]], (np.pi / 2, np.pi / 2))):  # north
                tg = np.array(targets)
                r.field.set_targets(tg, np.array(headings))
                for camera in (tg[0], tg.mean(axis=0)):
                    eye = cell_to_enu(camera, 2.0)
                    eye[2] = 3.44
                    blobs = find_blobs(r.camera.render_enu(eye))
                    assert len(blobs) == 2, (seed, targets, headings, camera)
                    seen = np.array([b.offset_ne(3.44) for b in blobs])
                    true = cell_to_ned(tg) - cell_to_ned(camera)
                    err = np.abs(seen[:, None] - true[None]).max(axis=-1)
                    assert sorted(err.argmin(axis=1).tolist()) == [0, 1] and err.min(axis=1).max() < 0.45
        finally:
            r.close()


def test_the_legs_of_cows_beyond_the_frame_are_not_targets() -> None:
    """Two cows 4 m south, their backs beyond the frame: their legs are lower, so nearer the
    nadir in the image, and one shows as a 4 px speck inside the frame. Read as a target in the
    next cell, the policy went back and forth to that empty cell for 290 moves (flight seed 59)."""
    from autopilot_bridge.detection.detector import find_blobs
    from autopilot_bridge.detection.view import blobs_to_view
    from sim.gridworld import cell_to_ned
    from sim.vehicle.frames import ned_to_enu

    r = ViewRenderer(10, 10, 2, image=50, seed=0)
    try:
        r.field.set_targets(np.array([[6.0, 3.0], [7.0, 3.0]]), np.array([-1.43, -1.16]))
        frame = r.camera.render_enu(ned_to_enu(np.array([-2.0, 11.6, -3.43])))  # over cell (6, 1), 0.4 m west
        from scipy import ndimage

        off = np.linalg.norm(frame.astype(float) - np.median(frame.reshape(-1, 3), axis=0), axis=-1) > 70
        lab, n = ndimage.label(off, np.ones((3, 3), bool))
        inside = [(lab[sl] == k + 1).sum() for k, sl in enumerate(ndimage.find_objects(lab))
                  if sl[0].start > 0 and sl[0].stop < 50 and sl[1].start > 0 and sl[1].stop < 50]
        assert inside and max(inside) <= 7, inside  # the speck is there
        blobs = find_blobs(frame)
        assert all(b.at_edge for b in blobs), [(b.row, b.col, b.pixels) for b in blobs]
        view = blobs_to_view(blobs, cell_to_ned(np.array([5.8, 1.0])), 3.37, np.array([6, 1]), 10, 10)
        assert not view[0].any()
    finally:
        r.close()


def test_a_single_cow_stays_one_target_whatever_its_heading() -> None:
    """The erosion that parts touching cows must not cut a cow's head off at the neck."""
    from autopilot_bridge.detection.detector import find_blobs
    from sim.vehicle.field import cell_to_enu

    rng = np.random.default_rng(5)
    for seed in range(3):
        r = ViewRenderer(10, 10, 1, image=50, seed=seed)
        try:
            for _ in range(20):
                r.field.set_targets(np.array([[5.0, 5.0]]), rng.uniform(-np.pi, np.pi, 1))
                eye = cell_to_enu(np.array([5.0, 5.0]) + rng.uniform(-0.5, 0.5, 2), 2.0)
                eye[2] = 3.44
                assert len(find_blobs(r.camera.render_enu(eye))) == 1, r.field.coats
        finally:
            r.close()


def test_a_target_beside_the_camera_lights_the_slot_it_lies_towards_never_the_centre() -> None:
    """A cow rendered 0.95 m east of the camera, in the camera's own cell but not under it: the
    policy would count the centre slot as a find, so show_beside lights the east slot."""
    from autopilot_bridge.detection.detector import find_blobs
    from autopilot_bridge.detection.view import blobs_to_view, show_beside
    from sim.gridworld import cell_to_ned
    from sim.vehicle.field import cell_to_enu

    r = ViewRenderer(10, 10, 1, image=50, seed=5)
    try:
        camera = np.array([5.0 - 0.475, 5.0])  # cells (x, y): 0.95 m west of the cow's cell centre
        r.field.set_targets(np.array([[5.0, 5.0]]))
        eye = cell_to_enu(camera, 2.0)
        eye[2] = 3.44
        blobs = find_blobs(r.camera.render_enu(eye))
        assert len(blobs) == 1
        n, e = blobs[0].offset_ne(3.44)
        assert 0.8 < e < 1.2 and abs(n) < 0.4
        cell = np.array([5, 5])
        # placed by a camera estimate at the cell's centre, the cow is in the centre slot ...
        assert blobs_to_view(blobs, cell_to_ned(cell), 3.44, cell, 10, 10)[0, 1, 1] == 1
        view = blobs_to_view([], cell_to_ned(cell), 3.44, cell, 10, 10)
        show_beside(view, blobs, 3.44, cell, 10, 10)
        # ... shown beside, it is in the east slot and only there
        assert view[0].tolist() == [[0, 0, 0], [0, 0, 1], [0, 0, 0]]
        # on the field's east edge there is no east slot: nothing is lit
        edge = np.array([9, 5])
        view = blobs_to_view([], cell_to_ned(edge), 3.44, edge, 10, 10)
        show_beside(view, blobs, 3.44, edge, 10, 10)
        assert view[0].sum() == 0
    finally:
        r.close()


def test_a_near_end_at_the_frame_edge_is_weighed_between_one_and_two_cells_out() -> None:
    """A cow whose near end shows at the frame's north edge is one cell north of a camera a
    metre and more south of its cell, or two cells north of one over its cell: the blob alone
    cannot tell, the position posterior weighs the two (far_likelihood), and nothing is
    placed beside the column it is in."""
    from autopilot_bridge.detection.detector import find_blobs
    from autopilot_bridge.detection.view import far_likelihood
    from sim.gridworld import cell_to_ned
    from sim.vehicle.camera import ALTITUDE_M

    r = ViewRenderer(10, 10, 1, image=50, seed=3)
    try:
        cell = np.array([5, 5])
        sure = np.eye(2) * 0.05
        shown = [0, 0]
        for heading in (0.0, 0.8, 1.6):
            r.field.set_targets(np.array([[5.0, 3.0]]), np.array([heading]))
            # two cells north of a camera over its cell
            blobs = [b for b in find_blobs(r.render_view(WorldState(10, 10, np.array([[5.0, 3.0]])), cell))
                     if b.beyond_view(ALTITUDE_M)]
            shown[0] += len(blobs)
            for b in blobs:
                lik = far_likelihood(b, cell_to_ned(cell), sure, cell, ALTITUDE_M, 10, 10)
                assert lik[3, 5] / lik.sum() > 0.95, lik
                assert lik[:, 4].sum() + lik[:, 6].sum() < 0.05 * lik.sum()
            # one cell north of a camera 1.3 m south of its cell (5, 4): a posterior that knows
            # it puts the cow a cell out; one centred on the cell (sd 0.7 m) keeps both
            off = np.array([5.0, 4.65])
            blobs = [b for b in find_blobs(r.render_view(WorldState(10, 10, np.array([[5.0, 3.0]])), off))
                     if b.beyond_view(ALTITUDE_M)]
            at = np.array([5, 4])
            shown[1] += len(blobs)
            for b in blobs:
                lik = far_likelihood(b, cell_to_ned(off), sure, at, ALTITUDE_M, 10, 10)
                assert lik[3, 5] / lik.sum() > 0.95, lik
                wide = far_likelihood(b, cell_to_ned(at), np.eye(2) * 0.49, at, ALTITUDE_M, 10, 10)
                assert 0.05 < wide[3, 5] / (wide[3, 5] + wide[2, 5]) < 0.95, wide
        assert min(shown) >= 2, shown
    finally:
        r.close()


def test_the_detector_reads_frames_from_any_height_into_its_levels_window() -> None:
    """From 5.83 m and 8.17 m (altitude levels 2 and 3: 5 x 5 and 7 x 7 views) each cow lights
    its own cell of the window; the blob sizes follow the height told (at 8.17 m a cow is ~10 px,
    under the 12 px a whole blob needs at 3.44 m: the nadir cow was lost when the height was not
    told). Told 3.44 m, or nothing, the detector is today's to the pixel count."""
    import pybullet as p

    from autopilot_bridge.detection.detector import (
        MIN_WHOLE_PX,
        BlobSizes,
        DetectorConfig,
        blobs_to_window,
        find_blobs,
        pixel_scale,
    )
    from sim.vehicle.camera import DownCamera
    from sim.vehicle.field import Field, cell_to_enu

    assert pixel_scale(3.44, 50) == 1.0 and BlobSizes.at(1.0) == BlobSizes(4, 12, 16, 20, 1)
    cid = p.connect(p.DIRECT)
    try:
        field = Field(cid, 20, 20, 5, seed=5, edge=True, margin_cells=8)
        camera = DownCamera(cid, 50, 50)
        cows = np.array([[10, 10], [11, 9], [8, 12], [13, 7], [7, 12]])  # rings 0, 1, 2, 3, 3 from (10, 10)
        field.set_targets(cows)
        offset = np.array([0.3, -0.25])  # the camera's (north, east) m off the cell's centre
        for height, radius, want in ((35 / 6, 2, cows[:3]), (49 / 6, 3, cows)):
            eye = cell_to_enu(np.array([10.0, 10.0]) + np.array([offset[1], -offset[0]]) / 2.0)
            eye[2] = height - 0.06
            frame = camera.render_enu(eye, (0.004, -0.006, 0.01))
            lit = blobs_to_window(find_blobs(frame, DetectorConfig(), height - 0.06), offset, height - 0.06, radius)
            expect = np.zeros_like(lit)
            for x, y in want:
                expect[y - 10 + radius, x - 10 + radius] = True
            assert (lit == expect).all(), (height, np.argwhere(lit), np.argwhere(expect))
        small = [b.pixels for b in find_blobs(frame, DetectorConfig(), 49 / 6 - 0.06)]
        assert min(small) < MIN_WHOLE_PX and not blobs_to_window(find_blobs(frame), offset, 49 / 6 - 0.06, 3)[3, 3]
        eye[2] = 3.44
        low = camera.render_enu(eye)
        assert find_blobs(low) == find_blobs(low, DetectorConfig(), 3.44) != []
    finally:
        p.disconnect(cid)
