"""End to end: `uavsearch train --model searchnet` writes a resumable run and a checkpoint with
provenance that the registry loads (weights only) and the evaluation runs."""

import subprocess
import sys

import pytest
import torch

from policy.baselines.registry import make_policy
from policy.evaluation.runner import evaluate
from policy.nn import CheckpointError
from policy.searchnet import read_searchnet
from sim.gridworld import GridConfig

ARGS = ["--model", "searchnet", "--dagger-iterations", "2", "--dagger-episodes", "24", "--ppo-updates", "2",
        "--ppo-episodes", "16", "--val-episodes", "40", "--width", "5", "--height", "5", "--targets", "2"]


def _train(out, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "missions", "train", "--out", str(out), *ARGS, *extra],
                          capture_output=True, text=True, timeout=240)


@pytest.mark.slow
def test_train_resume_and_load(tmp_path) -> None:
    out = tmp_path / "run"
    r = _train(out)
    assert r.returncode == 0, r.stderr
    doc = read_searchnet(out / "searchnet.pt")
    assert doc["grid"]["width"] == 5 and doc["seed"] == 0 and doc["git_revision"]
    assert doc["train"]["dagger"]["iterations"] == 2 and "val_moves" in doc["metrics"]
    torch.load(out / "searchnet.pt", weights_only=True)  # plain data: loads without unpickling code
    state = read_searchnet(out / "state.pt")
    assert state["stage"] == "done" and len(state["history"]) == 4
    # a second run in the same directory must be asked to resume; resuming a finished run is a no-op
    again = _train(out)
    assert again.returncode != 0 and "--resume" in again.stdout + again.stderr
    before = (out / "searchnet.pt").read_bytes()
    assert _train(out, "--resume").returncode == 0
    assert (out / "searchnet.pt").read_bytes() == before

    grid = GridConfig(width=5, height=5, n_targets=2)
    pol = make_policy("searchnet", grid, checkpoint=out / "searchnet.pt")
    res = evaluate(pol, grid, 20, seed=0, progress=False)
    assert res.moves.shape == (20,) and (res.moves >= res.optimal).all()


def test_a_foreign_file_is_a_clear_error(tmp_path) -> None:
    bad = tmp_path / "x.pt"
    torch.save({"format": "something-else"}, bad)
    with pytest.raises(CheckpointError, match="searchnet"):
        make_policy("searchnet", GridConfig(), checkpoint=bad)
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match="not a readable"):
        read_searchnet(bad)


@pytest.mark.slow
def test_fine_tune_from_a_checkpoint(tmp_path) -> None:
    """--init: the given network is validated first (the mark to beat) and drives DAgger from
    iteration 0; without --init, 0 DAgger iterations is refused with the option named."""
    from policy.belief import BELIEF_CHANNELS
    from policy.searchnet import SearchNet, SearchNetConfig
    from policy.searchnet.checkpoint import save_searchnet

    torch.manual_seed(1)
    start = save_searchnet(tmp_path / "start.pt", SearchNet(SearchNetConfig(BELIEF_CHANNELS)))
    tiny = ["--dagger-episodes", "12", "--ppo-updates", "0", "--val-episodes", "40", "--width", "5", "--height", "5", "--targets", "2"]
    cmd = [sys.executable, "-m", "missions", "train", "--model", "searchnet", *tiny]
    r = subprocess.run([*cmd, "--out", str(tmp_path / "ft"), "--init", str(start), "--dagger-iterations", "1",
                        "--dagger-beta0", "0.5"], capture_output=True, text=True, timeout=240)
    assert r.returncode == 0, r.stderr
    state = read_searchnet(tmp_path / "ft" / "state.pt")
    assert state["train"]["init"] == str(start) and state["stage"] == "done"
    (it,) = state["history"]
    assert it["beta"] == 0.5  # the student drove half the moves of the first iteration
    best = read_searchnet(tmp_path / "ft" / "searchnet.pt")
    assert best["metrics"]["val_moves"] <= state["best"]["val_moves"] + 1e-9
    # a finished run can be extended: more DAgger iterations (before PPO), then more PPO updates
    # (a repeated option's last value wins)
    ft = [*cmd, "--out", str(tmp_path / "ft"), "--init", str(start), "--dagger-beta0", "0.5", "--resume"]
    assert subprocess.run([*ft, "--dagger-iterations", "2"], capture_output=True, timeout=240).returncode == 0
    state = read_searchnet(tmp_path / "ft" / "state.pt")
    assert [h["beta"] for h in state["history"]] == [0.5, 0.25] and state["stage"] == "done"
    r = subprocess.run([*ft, "--dagger-iterations", "2", "--ppo-updates", "1"], capture_output=True, text=True,
                       timeout=240)
    assert r.returncode == 0, r.stderr
    state = read_searchnet(tmp_path / "ft" / "state.pt")
    assert [h["stage"] for h in state["history"]] == ["dagger", "dagger", "ppo"]
    late = subprocess.run([*ft, "--dagger-iterations", "3", "--ppo-updates", "1"], capture_output=True, text=True,
                          timeout=240)
    assert late.returncode != 0 and "extended" in late.stdout + late.stderr
    bad = subprocess.run([*cmd, "--out", str(tmp_path / "bad"), "--dagger-iterations", "0"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode != 0 and "init" in bad.stdout + bad.stderr
