"""SIGTERM on `uavsearch sitl --tlog` finalises the log: renamed from .part, provenance beside
it, readable by pymavlink (a killed-by-signal run used to leave only NAME.part)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from pymavlink import mavutil

ROOT = Path(__file__).resolve().parents[2]


def test_sigterm_finalises_the_tlog_with_provenance(tmp_path: Path) -> None:
    p = subprocess.Popen([sys.executable, "-m", "missions", "sitl", "--tlog", str(tmp_path / "v.tlog"), "--physics",
                          "kinematic", "--instance", "39", "--field-out", str(tmp_path / "f.json"),
                          "--bind", "127.0.0.1"], cwd=ROOT,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        end = time.monotonic() + 60
        while time.monotonic() < end and not list(tmp_path.glob("v*.tlog.part")):
            time.sleep(0.2)
        time.sleep(2.0)  # some telemetry in the log
        assert list(tmp_path.glob("v*.tlog.part")), "sitl never started its log"
    finally:
        p.send_signal(signal.SIGTERM)
        out, _ = p.communicate(timeout=30)
    logs = list(tmp_path.glob("v*.tlog"))
    assert len(logs) == 1 and not list(tmp_path.glob("*.part")), out
    meta = json.loads(logs[0].with_name(logs[0].name + ".json").read_text())
    assert meta["kind"] == "sitl tlog" and "git_revision" in meta
    log = mavutil.mavlink_connection(str(logs[0]))
    assert log.recv_match(type="HEARTBEAT") is not None


def test_a_bad_bind_address_is_refused_by_name(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from missions.cli import app

    r = CliRunner().invoke(app, ["sitl", "--bind", "nowhere", "--duration", "1", "--field-out", str(tmp_path / "f.json")])
    assert r.exit_code == 2 and "nowhere" in r.output, r.output
