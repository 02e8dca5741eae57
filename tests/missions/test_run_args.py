"""`uavsearch run` refuses bad flight arguments before anything connects or takes off, with a
message naming the value."""

import json
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app
from missions.fieldfile import FieldSpec, read_field, write_field
from sim.gridworld import GridConfig
from sim.gridworld.geodesy import HomePosition

runner = CliRunner()
ORIGIN = ["--origin-lat", "51.45", "--origin-lon", "-2.58", "--connect", "udpin:127.0.0.1:14997"]


def _text(output: str) -> str:
    return " ".join(output.replace("│", " ").split())


def test_bad_flight_arguments_are_refused_by_value(tmp_path: Path) -> None:
    for args, words in ((["--altitude", "-3"], ["-3", "--altitude"]), (["--altitude", "nan"], ["nan", "finite"]),
                        (["--max-moves", "0"], ["0", "--max-moves"]), (["--cell-m", "3"], ["3.0", "--cell-m"]), (["--move-timeout", "0"], ["--move-timeout"]),
                        (["--targets", "0"], ["n_targets"]), (["--policy", "nope"], ["unknown policy", "nope"]),
                        (["--policy", "oracle"], ["oracle", "truth"]),
                        (["--checkpoint", str(tmp_path / "x.pt")], ["x.pt", "does not exist"])):
        r = runner.invoke(app, ["run", *ORIGIN, "--out", str(tmp_path / "o"), *args])
        assert r.exit_code == 2, (args, r.output)
        assert all(w in _text(r.output) for w in words), (args, r.output)
    r = runner.invoke(app, ["run", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--field" in _text(r.output), "no origin: say how to give one"
    assert not (tmp_path / "o").exists(), "nothing was flown or written"


def test_a_policy_that_cannot_serve_the_size_says_so_before_take_off(tmp_path: Path) -> None:
    r = runner.invoke(app, ["run", *ORIGIN, "--width", "20", "--policy", "dualstream", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "20 x 10" in _text(r.output) and "dualstream" in _text(r.output), r.output


def test_field_file_round_trip_and_errors(tmp_path: Path) -> None:
    spec = FieldSpec(HomePosition(51.0, -2.0, 12.0), GridConfig(width=7, height=5, n_targets=2, motion="herd"),
                     2.0, "udpin:0.0.0.0:14541", 1, "pybullet", edge=True)
    write_field(tmp_path / "f.json", spec, seed=3)
    back = read_field(tmp_path / "f.json")
    assert back.grid.width == 7 and back.grid.motion == "herd" and back.origin == spec.origin and back.edge
    # a field file from before the edge was rendered has none; a bad value names itself
    d = json.loads((tmp_path / "f.json").read_text())
    (tmp_path / "old.json").write_text(json.dumps({k: v for k, v in d.items() if k != "edge"}))
    assert read_field(tmp_path / "old.json").edge is False
    (tmp_path / "edge.json").write_text(json.dumps({**d, "edge": "yes"}))
    r = runner.invoke(app, ["run", "--field", str(tmp_path / "edge.json")])
    assert r.exit_code == 2 and "edge" in _text(r.output) and "'yes'" in _text(r.output), r.output
    assert json.loads((tmp_path / "f.json").read_text())["provenance"]["seed"] == 3
    (tmp_path / "bad.json").write_text('{"kind": "uavsearch field", "width": "x"}')
    for name, words in (("missing.json", ["missing.json", "does not exist"]), ("bad.json", ["bad.json", "bad or missing"])):
        r = runner.invoke(app, ["run", "--field", str(tmp_path / name)])
        assert r.exit_code == 2 and all(w in _text(r.output) for w in words), r.output


def test_a_video_camera_without_its_sdp_or_stream_is_refused_by_name(tmp_path: Path) -> None:
    for args, words in ((["--camera", "udp://:27360"], ["--camera", "udp://:27360", "SDP file"]),
                        (["--camera", "udp://:27360", "--video-sdp", str(tmp_path / "no.sdp")],
                         ["no.sdp", "cannot be read"]),
                        (["--camera", "video"], ["names no video stream", "--video-port"])):
        r = runner.invoke(app, ["run", *ORIGIN, "--out", str(tmp_path / "o"), *args])
        assert r.exit_code == 2, (args, r.output)
        assert all(w in _text(r.output) for w in words), (args, r.output)


def test_a_real_field_sets_the_grid_and_origin(tmp_path: Path) -> None:
    """`run --field field.json` (a real field, `uavsearch field`): its grid and origin are not to
    be changed by hand; a hand-edited field is refused naming the file."""
    real = Path(__file__).parents[2] / "examples" / "fields" / "out" / "pond_meadow" / "field.json"
    r = runner.invoke(app, ["run", "--field", str(real), "--width", "5", "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--width" in _text(r.output) and "sets it" in _text(r.output), r.output
    bad = json.loads(real.read_text())
    bad["mask"][5] = bad["mask"][5].replace("s", "x", 1)
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    r = runner.invoke(app, ["run", "--field", str(tmp_path / "bad.json"), "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "bad.json" in _text(r.output) and "mask" in _text(r.output), r.output
    assert not (tmp_path / "o").exists()
