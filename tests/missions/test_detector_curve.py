"""`uavsearch detector-curve`: the grid world's detection table, measured on the SITL's camera."""

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from missions.cli import app
from missions.detector_curve import CurveConfig, clopper_pearson, level_height_m, measure

runner = CliRunner()


def test_the_curve_command_writes_the_table_the_grid_world_reads(tmp_path: Path) -> None:
    r = runner.invoke(app, ["detector-curve", "--frames", "36", "--seed", "3", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    d = json.loads((tmp_path / "detection.json").read_text())
    assert d["format"] == "uavsearch.detection/1" and d["levels"] == [1, 2, 3] and d["frames"] == 36
    assert d["height_m"] == [3.5, 5.83, 8.17] and d["view_radius"] == [1, 2, 3]
    assert [len(row) for row in d["p_detect"]] == [2, 3, 4] and len(d["false_alarm_per_cell"]) == 3
    assert all(0 <= v <= 1 for row in d["p_detect"] for v in row)
    counts = d["intervals"]["counts"]
    assert counts["frames"] == [12, 12, 12] and all(sum(t) > 0 for t in counts["targets"])
    assert d["provenance"]["seed"] == 3 and d["provenance"]["config"]["camera_px"] == 50
    assert "git_revision" in d["provenance"] and "--frames 36" in d["provenance"]["command"]
    assert (tmp_path / "curve.png").stat().st_size > 1000 and "| level |" in (tmp_path / "report.md").read_text()
    r = runner.invoke(app, ["detector-curve", "--frames", "3", "--camera-px", "10", "--out", str(tmp_path)])
    assert r.exit_code == 2 and "--camera-px" in r.output


def test_the_same_seed_measures_the_same_counts_and_the_camera_renders_at_its_size() -> None:
    cfg = CurveConfig(frames=6, seed=11, camera_px=64, levels=(1, 3), frames_per_field=4)
    a, b = measure(cfg), measure(cfg)
    assert all((a[lv].targets == b[lv].targets).all() and (a[lv].seen == b[lv].seen).all() for lv in (1, 3))
    assert a[3].targets.shape == (4,) and a[1].frames == a[3].frames == 3
    with pytest.raises(ValueError, match="frames"):
        CurveConfig(frames=1)
    import pybullet as p

    from sim.gridworld import GridConfig
    from sim.vehicle.geo import HomePosition
    from sim.vehicle.scene import FieldScene

    cid = p.connect(p.DIRECT)
    try:
        scene = FieldScene(GridConfig(), HomePosition(), 0, 4.0)
        scene.attach(cid, 0, True, 64)
        assert scene.render(0.0, np.array([0.0, 0.0, -49 / 6]), 0.0, (0.01, 0.0, 0.0)).shape == (64, 64, 3)
        with pytest.raises(ValueError, match="camera_px"):
            scene.attach(cid, 0, True, 2000)
    finally:
        p.disconnect(cid)


def test_clopper_pearson_and_the_levels_heights() -> None:
    lo, hi = clopper_pearson(0, 10)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** 0.1)
    lo, hi = clopper_pearson(10, 10)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** 0.1)
    assert clopper_pearson(0, 0) == (0.0, 1.0)
    assert np.allclose([level_height_m(v) for v in (1, 2, 3)], [3.5, 35 / 6, 49 / 6])
