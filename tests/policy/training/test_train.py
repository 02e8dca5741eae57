import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from policy.data import synthesize
from policy.nn import load_model
from policy.training import TrainConfig, train
from sim.gridworld import GridConfig


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return synthesize(GridConfig(), 150, 0, tmp_path_factory.mktemp("ds") / "ds", progress=False)


def test_short_training_reduces_the_loss_and_writes_everything(dataset: Path, tmp_path: Path) -> None:
    tc = TrainConfig(epochs=3, folds=3, run_folds=2, batch=64, optimizer="adam", seed=1)
    s = train(dataset, tmp_path, tc, progress=False)
    rows = [r.split(",") for r in (tmp_path / "metrics.csv").read_text().splitlines()[1:]]
    fold0 = [float(r[2]) for r in rows if r[0] == "0"]
    assert fold0[-1] < fold0[0], "training loss goes down"
    assert len(s["folds"]) == 2 and 0.0 <= s["cv_acc_mean"] <= 1.0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["git_revision"] and summary["seed"] == 1 and summary["config"]["n_targets"] == 5
    _, doc = load_model(tmp_path / "model.pt")
    assert doc["fold"] == summary["best_fold"]
    assert (tmp_path / "training_curve.png").read_bytes()[:4] == b"\x89PNG"
    assert any((tmp_path / "tensorboard").iterdir())


def test_resume_gives_the_same_weights_as_an_uninterrupted_run(dataset: Path, tmp_path: Path) -> None:
    tc = TrainConfig(epochs=3, folds=3, run_folds=2, batch=32, seed=4)
    train(dataset, tmp_path / "full", tc, progress=False)
    # A real interruption: run training in a child process and kill it mid-run.
    code = (
        "import sys; from policy.training import TrainConfig, train; "
        "train(sys.argv[1], sys.argv[2], TrainConfig(epochs=3, folds=3, run_folds=2, batch=32, seed=4), "
        "progress=False)"
    )
    cut = tmp_path / "cut"
    child = subprocess.Popen([sys.executable, "-c", code, str(dataset), str(cut)])
    metrics = cut / "metrics.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and child.poll() is None:
        if metrics.exists() and metrics.read_text().count("\n") >= 3:  # header + 2 epochs
            break
        time.sleep(0.05)
    child.kill()
    child.wait()
    assert not (cut / "fold1.pt").exists(), "the child was stopped before the run finished"
    train(dataset, cut, tc, resume=True, progress=False)
    a, _ = load_model(tmp_path / "full" / "fold1.pt")
    b, _ = load_model(cut / "fold1.pt")
    for x, y in zip(a.state_dict().values(), b.state_dict().values(), strict=True):
        assert torch.equal(x, y)
    assert (tmp_path / "full" / "metrics.csv").read_text().count("\n") == metrics.read_text().count("\n")


def test_resume_with_other_options_is_refused(dataset: Path, tmp_path: Path) -> None:
    train(dataset, tmp_path, TrainConfig(epochs=1, folds=2, run_folds=1), progress=False)
    with pytest.raises(ValueError, match="another training config"):
        train(dataset, tmp_path, TrainConfig(epochs=2, folds=2, run_folds=1), resume=True, progress=False)


def test_bad_config() -> None:
    with pytest.raises(ValueError):
        TrainConfig(folds=1)
    with pytest.raises(ValueError):
        TrainConfig(optimizer="rmsprop")
