import numpy as np
import pytest

from sim.vehicle import GpsConfig, GpsModel, HomePosition, ViewRenderer, WorldState, from_e7, to_e7


def test_geodetic_round_trip_is_sub_millimetre_within_2_km() -> None:
    home = HomePosition(51.4545, -2.5879, 30.0)
    rng = np.random.default_rng(0)
    for ned in rng.uniform(-2000, 2000, (50, 3)):
        back = home.geodetic_to_ned(*home.ned_to_geodetic(ned))
        assert np.abs(back - ned).max() < 1e-3
    lat, lon, alt = home.ned_to_geodetic(np.array([111.2, 0, -10]))
    assert abs(lat - home.lat_deg - 0.001) < 2e-5 and alt == pytest.approx(40.0)
    assert from_e7(to_e7(51.4545123)) == pytest.approx(51.4545123, abs=1e-7)
    with pytest.raises(ValueError):
        HomePosition(95.0, 0.0)


def test_gps_noise_statistics_rate_and_seed() -> None:
    home = HomePosition()
    cfg = GpsConfig(rate_hz=5.0, sigma_h=0.6, bias_sigma_h=0.7, bias_tau_s=60.0)
    gps = GpsModel(home, seed=3, cfg=cfg)
    fixes, errs = 0, []
    t = 0.0
    while t < 600.0:
        f = gps.sample(t, np.zeros(3), np.zeros(3))
        if f is not None:
            fixes += 1
            errs.append(home.geodetic_to_ned(f.lat_deg, f.lon_deg, f.alt_m))
        t += 0.05
    errs = np.array(errs)
    assert abs(fixes - 3000) <= 2, "5 Hz"
    # total horizontal error: white 0.6 and bias 0.7 -> about 0.92 per axis over long runs
    assert 0.5 < errs[:, 0].std() < 1.4
    # the bias drifts slowly: consecutive fixes are strongly correlated beyond the white noise
    d = np.diff(errs[:, 0])
    assert d.std() < 1.2 * np.sqrt(2) * 0.6
    again = GpsModel(home, seed=3, cfg=cfg).sample(0.0, np.zeros(3), np.zeros(3))
    first = GpsModel(home, seed=3, cfg=cfg).sample(0.0, np.zeros(3), np.zeros(3))
    assert again.lat_deg == first.lat_deg and again.fix_type == 3 and again.eph_m > 0


@pytest.fixture(scope="module")
def renderer():
    r = ViewRenderer(10, 10, 2, image=50, seed=1)
    yield r
    r.close()


def test_camera_sees_a_cow_below_and_north_is_up(renderer) -> None:
    far = WorldState(10, 10, np.array([[9.0, 9.0], [0.0, 9.0]]))
    empty = renderer.render_view(far, np.array([4, 4])).astype(int)
    assert empty.shape == (50, 50, 3)
    below = renderer.render_view(WorldState(10, 10, np.array([[4.0, 4.0], [0.0, 9.0]])), np.array([4, 4])).astype(int)
    diff = np.abs(below - empty).sum(-1) > 30
    assert diff[20:30, 20:30].mean() > 0.3, "a cow right below fills the image centre"
    north = renderer.render_view(WorldState(10, 10, np.array([[4.0, 3.0], [0.0, 9.0]])), np.array([4, 4])).astype(int)
    d = np.abs(north - empty).sum(-1) > 30
    assert d[:25].sum() > 3 * d[25:].sum(), "a cow one cell north (-y) shows in the top half"
    east = renderer.render_view(WorldState(10, 10, np.array([[5.0, 4.0], [0.0, 9.0]])), np.array([4, 4])).astype(int)
    d = np.abs(east - empty).sum(-1) > 30
    assert d[:, 25:].sum() > 3 * d[:, :25].sum(), "a cow one cell east (+x) shows on the right"


def test_batch_render_shapes(renderer) -> None:
    tg = np.array([[[1, 1], [2, 2]], [[3, 3], [4, 4]]])
    out = renderer.render_views(tg, np.array([[1, 1], [0, 0]]), 10, 10)
    assert out.shape == (2, 3, 50, 50) and out.dtype == np.uint8
    assert not np.array_equal(out[0], out[1])


def _reference_fixes(home: HomePosition, seed: int, cfg: GpsConfig, times: np.ndarray, pos: np.ndarray,
                     vel: np.ndarray) -> list:
    """The receiver as first written (three rng.normal calls a fix, scales as lists): the
    shipped one draws once a fix and must give the same numbers."""
    rng = np.random.default_rng([seed, 0x6905])
    bias = rng.normal(0, [cfg.bias_sigma_h, cfg.bias_sigma_h, cfg.bias_sigma_v])
    baro_rng = np.random.default_rng([seed, 0xBA20])
    baro = float(baro_rng.normal(0, cfg.baro_sigma_m))
    out, nxt, last = [], 0.0, None
    for t, p, v in zip(times, pos, vel, strict=True):
        if t + 1e-9 < nxt:
            out.append(None)
            continue
        if last is not None:
            a = np.exp(-(t - last) / cfg.bias_tau_s)
            sd = np.array([cfg.bias_sigma_h, cfg.bias_sigma_h, cfg.bias_sigma_v]) * np.sqrt(1 - a * a)
            bias = a * bias + rng.normal(0, sd)
            ab = np.exp(-(t - last) / cfg.baro_tau_s)
            baro = float(ab * baro + baro_rng.normal(0, cfg.baro_sigma_m * np.sqrt(1 - ab * ab)))
        last, nxt = t, t + 1.0 / cfg.rate_hz
        noisy = p + bias + rng.normal(0, [cfg.sigma_h, cfg.sigma_h, cfg.sigma_v])
        err = np.array([bias[0], bias[1], baro]) if cfg.height_from_baro else bias.copy()
        out.append((home.ned_to_geodetic(noisy), v + rng.normal(0, cfg.sigma_vel, 3), err))
    return out


@pytest.mark.parametrize("cfg", [GpsConfig(), GpsConfig(rate_hz=10.0, sigma_h=0.0, bias_sigma_v=0.0, sigma_vel=0.0),
                                 GpsConfig(rate_hz=1.0, height_from_baro=False, bias_tau_s=5.0)])
def test_gps_fixes_are_the_same_numbers_as_the_three_draw_receiver(cfg: GpsConfig) -> None:
    home = HomePosition()
    rng = np.random.default_rng(7)
    times = np.cumsum(rng.uniform(0.005, 0.05, 2000))  # uneven ticks: dt varies from fix to fix
    pos, vel = rng.normal(0, 30, (2000, 3)), rng.normal(0, 3, (2000, 3))
    gps = GpsModel(home, seed=11, cfg=cfg)
    ref = _reference_fixes(home, 11, cfg, times, pos, vel)
    fixes = 0
    for t, p, v, r in zip(times, pos, vel, ref, strict=True):
        f = gps.sample(float(t), p, v)
        assert (f is None) == (r is None)
        if f is not None:
            fixes += 1
            assert (f.lat_deg, f.lon_deg, f.alt_m) == r[0]
            assert np.array_equal(f.vel_ned, r[1]) and np.array_equal(gps.estimate_error, r[2])
    assert fixes > 40
