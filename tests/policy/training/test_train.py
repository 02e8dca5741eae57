import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from policy.data import synthesize
from policy.nn import CheckpointError, build_model, load_model
from policy.training import TrainConfig, kfold_split, plot_runs, train
from policy.training.metrics_log import read_csv
from sim.gridworld import GridConfig


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    return synthesize(GridConfig(), 150, 0, tmp_path_factory.mktemp("ds") / "ds", progress=False)


def _same_weights(a: Path, b: Path) -> bool:
    x, _ = load_model(a)
    y, _ = load_model(b)
    return all(torch.equal(p, q) for p, q in zip(x.state_dict().values(), y.state_dict().values(), strict=True))


def test_kfold_split_is_a_seeded_partition() -> None:
    folds = kfold_split(103, 10, seed=5)
    assert len(folds) == 10 and {len(f) for f in folds} <= {10, 11}
    assert np.array_equal(np.sort(np.concatenate(folds)), np.arange(103))
    assert all(np.array_equal(a, b) for a, b in zip(folds, kfold_split(103, 10, seed=5), strict=True))
    assert not np.array_equal(folds[0], kfold_split(103, 10, seed=6)[0])
    with pytest.raises(ValueError, match="k-fold"):
        kfold_split(5, 10, seed=0)


def test_short_training_reduces_the_loss_and_writes_everything(dataset: Path, tmp_path: Path) -> None:
    tc = TrainConfig(epochs=3, folds=3, run_folds=2, batch=64, optimizer="adam", seed=1)
    s = train(dataset, tmp_path, tc, progress=False)
    rows = read_csv(tmp_path / "metrics.csv")
    fold0 = [r["train_loss"] for r in rows if r["fold"] == 0]
    assert len(rows) == 6 and fold0[-1] < fold0[0], "training loss goes down"
    assert len(s["folds"]) == 2 and 0.0 <= s["cv_acc_mean"] <= 1.0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["git_revision"] and summary["seed"] == 1 and summary["config"]["n_targets"] == 5
    assert summary["cv_acc_mean"] == pytest.approx(np.mean([f["val_acc"] for f in summary["folds"]]))
    _, doc = load_model(tmp_path / "model.pt")
    assert doc["fold"] == summary["best_fold"] and doc["train_config"]["optimizer"] == "adam"
    assert doc["git_revision"] and doc["dataset_meta"]["seed"] == 0
    assert (tmp_path / "training_curve.png").read_bytes()[:4] == b"\x89PNG"
    assert any((tmp_path / "tensorboard" / "fold0").iterdir())
    assert not list(tmp_path.glob("*.partial.pt")), "finished folds leave no partial checkpoint"
    fig6 = plot_runs({"150 episodes": rows, "first fold": rows[:3]}, tmp_path / "fig6.png")
    assert fig6.read_bytes()[:4] == b"\x89PNG"


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
    fold0 = cut / "metrics" / "fold0.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and child.poll() is None:
        if fold0.exists() and fold0.read_text().count("\n") >= 3:  # header + 2 epochs
            break
        time.sleep(0.02)
    child.kill()
    child.wait()
    assert not (cut / "fold1.pt").exists(), "the child was stopped before the run finished"
    train(dataset, cut, tc, resume=True, progress=False)
    for k in (0, 1):
        assert _same_weights(tmp_path / "full" / f"fold{k}.pt", cut / f"fold{k}.pt")
    full_rows, cut_rows = read_csv(tmp_path / "full" / "metrics.csv"), read_csv(cut / "metrics.csv")
    strip = [{k: v for k, v in r.items() if k != "seconds"} for r in full_rows]
    assert strip == [{k: v for k, v in r.items() if k != "seconds"} for r in cut_rows]


def test_folds_in_parallel_processes_match_sequential_folds(dataset: Path, tmp_path: Path) -> None:
    tc = TrainConfig(epochs=1, folds=4, run_folds=2, batch=64, seed=2)
    seq = train(dataset, tmp_path / "seq", tc, progress=False)
    par = train(dataset, tmp_path / "par", tc, progress=False, workers=2)
    assert seq["folds"] == par["folds"]
    assert _same_weights(tmp_path / "seq" / "fold1.pt", tmp_path / "par" / "fold1.pt")


def test_ddp_over_two_gloo_processes_matches_one_process(dataset: Path, tmp_path: Path) -> None:
    """The DDP code path (NCCL on GPUs) run on CPU: the averaged gradients of two half-batches
    equal the full batch's, so the weights agree to float rounding."""
    common = dict(epochs=1, folds=4, run_folds=1, batch=64, lr=0.02, seed=3, max_samples=1200)
    train(dataset, tmp_path / "one", TrainConfig(**common), progress=False)
    s = train(dataset, tmp_path / "two", TrainConfig(**common, ddp=2), progress=False)
    a, doc = load_model(tmp_path / "one" / "fold0.pt")
    b, doc2 = load_model(tmp_path / "two" / "fold0.pt")
    assert doc2["train_config"]["ddp"] == 2 and len(s["folds"]) == 1
    torch.manual_seed(3 * 1000 + 0)  # the fresh network of fold 0 (seed * 1000 + fold)
    init = build_model(doc["model_config"]).state_dict()
    moved = max(float((x - init[k]).abs().max()) for k, x in a.state_dict().items())
    apart = max(float((x - y).abs().max()) for x, y in zip(a.state_dict().values(), b.state_dict().values(),
                                                           strict=True))
    assert moved > 1e-2, "training changed the weights"
    assert apart < 1e-4 * moved, f"DDP weights differ by {apart} (training moved them by {moved})"


def test_resume_with_other_options_or_data_is_refused(dataset: Path, tmp_path: Path) -> None:
    train(dataset, tmp_path, TrainConfig(epochs=1, folds=2, run_folds=1), progress=False)
    with pytest.raises(CheckpointError, match="another training config"):
        train(dataset, tmp_path, TrainConfig(epochs=2, folds=2, run_folds=1), resume=True, progress=False)
    other = synthesize(GridConfig(), 20, 9, tmp_path / "other", progress=False)
    with pytest.raises(CheckpointError, match="another dataset"):
        train(other, tmp_path, TrainConfig(epochs=1, folds=2, run_folds=1), resume=True, progress=False)


def test_bad_config() -> None:
    with pytest.raises(ValueError):
        TrainConfig(folds=1)
    with pytest.raises(ValueError):
        TrainConfig(optimizer="rmsprop")
    with pytest.raises(ValueError, match="DDP"):
        TrainConfig(batch=63, ddp=2)


def test_ray_address_without_ray_is_a_clear_error(dataset: Path, tmp_path: Path) -> None:
    import importlib.util

    if importlib.util.find_spec("ray") is not None:
        pytest.skip("ray is installed here; this checks the message for machines without it")
    with pytest.raises(RuntimeError, match="needs ray"):
        train(dataset, tmp_path, TrainConfig(epochs=1, folds=2), progress=False, ray_address="127.0.0.1:6379")
