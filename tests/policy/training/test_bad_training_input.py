"""Training refuses what would make a silently broken model: a NaN learning rate, a loss that
goes non-finite, and an --out that is a file."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from missions.cli import app
from policy.data import synthesize
from policy.training import TrainConfig
from policy.training import train as run
from sim.gridworld import GridConfig

runner = CliRunner()


@pytest.mark.parametrize("lr", [math.nan, math.inf, 0.0, -1.0])
def test_non_finite_or_non_positive_lr_is_refused(lr: float) -> None:
    with pytest.raises(ValueError, match="lr"):
        TrainConfig(lr=lr)


def _flat(output: str) -> str:
    """The error box's text on one line: rich wraps it at the terminal width (long tmp paths)."""
    return " ".join(output.replace("│", " ").split())


def test_cli_names_the_bad_value(tmp_path: Path) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    r = runner.invoke(app, ["train", "--out", str(afile), "--dataset", str(tmp_path)])
    assert r.exit_code == 2 and "is a file" in _flat(r.output), r.output
    r = runner.invoke(app, ["train", "--out", str(tmp_path / "o"), "--dataset", str(tmp_path), "--lr", "nan"])
    assert r.exit_code == 2 and "lr nan" in _flat(r.output), r.output


def test_a_diverging_run_stops_and_writes_no_model(tmp_path: Path) -> None:
    ds = synthesize(GridConfig(), 12, 0, tmp_path / "ds", progress=False)
    tc = TrainConfig(epochs=2, folds=2, run_folds=1, batch=16, optimizer="sgd", lr=1e30, seed=0)
    with pytest.raises(ValueError, match="diverged"):
        run(ds, tmp_path / "out", tc)
    assert not (tmp_path / "out" / "model.pt").exists()
