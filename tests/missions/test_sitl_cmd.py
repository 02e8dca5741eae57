"""`uavsearch sitl`: a second one on the same instance fails clearly; the field file it writes."""

import json
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app
from sim.mavlink import Sitl, SitlConfig

runner = CliRunner()


def test_second_sitl_on_the_same_instance_is_refused(tmp_path: Path) -> None:
    with Sitl(SitlConfig(instance=34, physics="kinematic", speedup=2.0, gcs_remote_port=14584)):
        r = runner.invoke(app, ["sitl", "--instance", "34", "--physics", "kinematic", "--duration", "1",
                                "--field-out", str(tmp_path / "f.json")])
    text = " ".join(r.output.replace("│", " ").split())
    assert r.exit_code == 2 and "14614 (API link of instance 34) is taken" in text, r.output
    assert not (tmp_path / "f.json").exists()


def test_sitl_writes_the_field_the_companion_needs(tmp_path: Path) -> None:
    r = runner.invoke(app, ["sitl", "--instance", "35", "--physics", "kinematic", "--speedup", "0", "--duration", "1",
                            "--width", "40", "--height", "30", "--targets", "7", "--motion", "herd",
                            "--lat", "10.5", "--field-out", str(tmp_path / "f.json")])
    assert r.exit_code == 0, r.output
    assert "uavsearch run --field" in r.output and "40 x 30 cells" in r.output
    d = json.loads((tmp_path / "f.json").read_text())
    assert (d["width"], d["height"], d["targets"], d["motion"], d["origin"]["lat"]) == (40, 30, 7, "herd", 10.5)
    assert d["connect"] == "udpin:0.0.0.0:14575" and d["provenance"]["sitl"]["geofence"]["max_horizontal_m"] > 100
    r = runner.invoke(app, ["sitl", "--cell-m", "3"])
    assert r.exit_code == 2 and "--cell-m" in r.output


def test_sitl_field_renders_a_real_field_and_names_it_for_the_companion(tmp_path: Path) -> None:
    from missions.fieldfile import read_field

    real = Path(__file__).parents[2] / "examples" / "fields" / "out" / "l_paddock_30deg" / "field.json"
    # instance 38: 34 is the refusal test's, the camera source test's and a fleet test's (33-34)
    r = runner.invoke(app, ["sitl", "--instance", "38", "--physics", "kinematic", "--speedup", "0", "--duration", "0.5",
                            "--field", str(real), "--width", "3", "--field-out", str(tmp_path / "f.json")])
    assert r.exit_code == 0, r.output
    assert "25 x 24 cells" in r.output and "heading 30.00 deg" in r.output
    fs = read_field(tmp_path / "f.json")
    assert (fs.grid.width, fs.grid.height, fs.polygon) == (25, 24, str(real.resolve()))
    assert abs(fs.origin.lat_deg - 51.4548218) < 1e-6, "the origin is the field's cell (0, 0)"
    r = runner.invoke(app, ["sitl", "--field", str(real), "--count", "2"])
    assert r.exit_code == 2 and "--field" in r.output


def test_sitl_video_port_writes_the_sdp_and_the_field_file_names_it(tmp_path: Path) -> None:
    from missions.fieldfile import read_field

    r = runner.invoke(app, ["sitl", "--instance", "36", "--physics", "kinematic", "--speedup", "0", "--duration", "0.5",
                            "--video-port", "27201", "--field-out", str(tmp_path / "f.json")])
    assert r.exit_code == 0, r.output
    assert "UDP h.264 Video Stream" in r.output and "port 27201" in r.output
    fs = read_field(tmp_path / "f.json")
    assert fs.video_uri == "udp://:27201" and fs.video_sdp == str(tmp_path / "f.sdp")
    assert "m=video 27201 RTP/AVP 96" in (tmp_path / "f.sdp").read_text()
    r = runner.invoke(app, ["sitl", "--video-port", "fast"])
    assert r.exit_code == 2 and "--video-port" in r.output


def test_sitl_camera_px_is_validated_before_anything_starts() -> None:
    import pytest

    for bad in ("8", "2048"):
        r = runner.invoke(app, ["sitl", "--instance", "37", "--physics", "kinematic", "--camera-px", bad])
        assert r.exit_code == 2 and "--camera-px" in r.output and "16..1024" in r.output, r.output
    with pytest.raises(ValueError, match="camera_px must be a whole number of pixels in 16..1024"):
        SitlConfig(camera_px=0)
    assert SitlConfig(camera_px=120).to_dict()["camera_px"] == 120
