"""`uavsearch sitl --autopilot ardupilot|px4`: what it refuses, by name, without a binary; with
one (ARDUPILOT_SITL / PX4_SITL set), the world runs the real autopilot and the field file says
who flies and where the companion connects."""

import json
import os
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from missions.cli import app
from missions.fieldfile import read_field
from sim.bridges.world import AutopilotWorld, AutopilotWorldConfig

runner = CliRunner()


def _text(output: str) -> str:
    return " ".join(output.replace("│", " ").split())


def test_refusals_name_the_option(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PX4_SITL", raising=False)
    monkeypatch.delenv("ARDUPILOT_SITL", raising=False)
    out = ["--field-out", str(tmp_path / "f.json"), "-i", "27"]
    for args, words in ((["--autopilot", "px4"], ["PX4_SITL", "--autopilot-bin"]),
                        (["--autopilot", "ardupilot"], ["ARDUPILOT_SITL"]),
                        (["--autopilot", "px4", "--autopilot-bin", str(tmp_path / "nope")], ["nope", "not an executable"]),
                        (["--autopilot", "px4", "--count", "2"], ["--count 1"]),
                        (["--autopilot", "ardupilot", "--physics", "kinematic"], ["PyBullet"]),
                        (["--autopilot", "ardupilot", "--speedup", "0"], ["--speedup > 0"])):
        r = runner.invoke(app, ["sitl", *out, *args])
        assert r.exit_code == 2, (args, r.output)
        assert all(w in _text(r.output) for w in words), (args, r.output)
    assert not (tmp_path / "f.json").exists()


def test_the_world_renders_the_field_for_a_camera_component() -> None:
    """The camera hook, without a binary: render() is today's SITL camera on the same field."""
    world = AutopilotWorld(AutopilotWorldConfig(autopilot="px4", instance=27, episode_seed=3, seed=3))
    try:
        img = world.render(np.array([0.0, 0.0, -3.5]), 0.0)
        assert img.shape == (50, 50, 3) and img.dtype == np.uint8 and img.std() > 1
        assert world.autopilot_clock_s() == pytest.approx(world.t + 1.0)  # PX4's clock: t + 1 s
        assert world.companion_address() == "udpout:127.0.0.1:14607"  # PX4 > 9 sends to 14549
        np.testing.assert_array_equal(world.target_cells(), world.scene.episode.targets[0])
    finally:
        world.stop()


@pytest.mark.skipif(not os.environ.get("PX4_SITL"), reason="PX4_SITL (the px4 SITL binary) is not set")
def test_px4_world_runs_and_writes_the_field_file(tmp_path: Path) -> None:
    f = tmp_path / "field.json"
    r = runner.invoke(app, ["sitl", "--autopilot", "px4", "-i", "26", "--speedup", "5", "--duration", "3",
                            "--field-out", str(f), "--seed", "4"])
    assert r.exit_code == 0, r.output
    spec = read_field(f)
    assert spec.autopilot == "px4" and spec.instance == 26 and spec.connect == "udpout:127.0.0.1:14606"
    assert json.loads(f.read_text())["provenance"]["sitl"]["autopilot"] == "px4"
