import json
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app

runner = CliRunner()


def _text(output: str) -> str:
    """Rich boxes wrap messages; compare on the words."""
    return " ".join(output.replace("│", " ").split())


def test_eval_json_is_machine_readable() -> None:
    res = subprocess.run(
        [sys.executable, "-m", "missions", "eval", "--policy", "oracle", "--episodes", "300", "--seed", "5", "--json"],
        capture_output=True, text=True, timeout=60,
    )
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)
    assert abs(doc["policies"]["oracle"]["mean_moves"] - 20.93) < 1.0


def test_eval_rejects_unknown_policy_and_bad_config() -> None:
    r = runner.invoke(app, ["eval", "--policy", "bogus"])
    assert r.exit_code != 0 and "unknown policy" in _text(r.output)
    r = runner.invoke(app, ["eval", "--targets", "0"])
    assert r.exit_code != 0 and "n_targets" in _text(r.output)


def test_synth_then_refuses_to_overwrite(tmp_path: Path) -> None:
    r = runner.invoke(app, ["synth", "--out", str(tmp_path / "ds"), "--episodes", "20"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "ds" / "meta.json").exists()
    r = runner.invoke(app, ["synth", "--out", str(tmp_path / "ds"), "--episodes", "20"])
    assert r.exit_code != 0 and "already holds a dataset" in _text(r.output)
    r = runner.invoke(app, ["synth", "--out", str(tmp_path / "cu"), "--episodes", "5", "--method", "cu", "--motion", "herd"])
    assert r.exit_code != 0


def test_sitl_command_runs_and_writes_readable_tlogs(tmp_path: Path) -> None:
    from pymavlink import mavutil

    r = runner.invoke(app, ["sitl", "--instance", "31", "--count", "2", "--physics", "kinematic", "--speedup", "0",
                            "--duration", "2", "--tlog", str(tmp_path / "f.tlog")])
    assert r.exit_code == 0, r.output
    # PX4 SITL numbering: API port 14540 + N, system id N + 1, GCS telemetry to the shared 14550
    assert "udpin://0.0.0.0:14571" in r.output and "MAVLink system 33" in r.output
    assert "udpin:0.0.0.0:14550" in r.output
    for n in (31, 32):
        log = mavutil.mavlink_connection(str(tmp_path / f"f-{n}.tlog"))
        assert log.recv_match(type="HEARTBEAT") is not None
    # a key on the command line would be readable by every user in /proc: only a key file is taken
    r = runner.invoke(app, ["sitl", "--signing-key", "00" * 32])
    assert r.exit_code == 2 and "No such option" in _text(r.output)


def test_train_drqn_by_reward_and_dataset_rules(tmp_path: Path) -> None:
    r = runner.invoke(app, ["train", "--out", str(tmp_path / "ds_run")])
    assert r.exit_code != 0 and "--dataset" in _text(r.output), "the dual-stream net needs a dataset"
    r = runner.invoke(app, ["train", "--model", "drqn", "--out", str(tmp_path / "h"), "--motion", "herd"])
    assert r.exit_code != 0 and "static" in _text(r.output)
    r = runner.invoke(app, ["train", "--model", "drqn", "--out", str(tmp_path / "d"), "--episodes", "16",
                            "--width", "6", "--height", "6", "--targets", "2"])
    assert r.exit_code == 0, r.output
    from policy.drqn import load_drqn

    _, doc = load_drqn(tmp_path / "d" / "drqn.pt")
    assert doc["grid_config"]["width"] == 6 and doc["drqn_config"]["episodes"] == 16 and doc["seed"] == 0
    assert (tmp_path / "d" / "drqn_state.pt").exists(), "a snapshot to resume or extend from"
    assert (tmp_path / "d" / "drqn_training.png").stat().st_size > 1000, "a training plot"
