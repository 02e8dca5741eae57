import json
from pathlib import Path

import pytest

from missions.table1 import run_table1
from policy.nn import shipped_checkpoint


def test_rows_end_to_end_then_one_row_again_keeps_the_rest(tmp_path: Path) -> None:
    out, work = tmp_path / "results", tmp_path / "work"
    doc = run_table1("smoke", out, seed=1, only=["NS", "DRQN", "Random (PT)"], workers=1, work=work)
    assert [r["row"] for r in doc["rows"]] == ["NS", "DRQN", "Random (PT)"]
    pt = doc["rows"][2]
    assert pt["episodes"] == 30 and pt["train_samples"] > 0 and 0 < pt["cv_acc_mean"] <= 100
    assert (work / "random__pt" / "run" / "model.pt").exists()
    assert doc["rows"][1]["drqn_checkpoint"] == str(work / "drqn" / "drqn" / "drqn.pt"), "the scale trains its DRQN"
    md = (out / "table1_smoke.md").read_text()
    assert "| Random (PT) | ours |" in md and "| Random (PT) | paper | 32.45" in md, "paper's figures beside ours"
    assert all(r["git_revision"] for r in doc["rows"]) and doc["seed"] == 1

    again = run_table1("smoke", out, seed=1, only=["DRQN"], workers=1, drqn_checkpoint=tmp_path / "none.pt",
                       work=work)
    rows = {r["row"]: r for r in again["rows"]}
    assert list(rows) == ["NS", "DRQN", "Random (PT)"], "the other rows are kept"
    assert "not_yet" in rows["DRQN"] and rows["Random (PT)"] == pt
    saved = json.loads((out / "table1_smoke.json").read_text())
    assert saved["rows"][1]["not_yet"].startswith("no DRQN checkpoint")
    assert "| DRQN | ours | not yet: no DRQN checkpoint" in (out / "table1_smoke.md").read_text()


def test_a_given_drqn_checkpoint_is_tested(tmp_path: Path) -> None:
    ckpt = shipped_checkpoint("drqn_static_random")
    doc = run_table1("smoke", tmp_path, only=["DRQN"], workers=1, drqn_checkpoint=ckpt, work=tmp_path / "w")
    assert doc["rows"][0]["drqn_checkpoint"] == str(ckpt) and doc["rows"][0]["episodes"] == 30


def test_unknown_rows_and_scales_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unknown row"):
        run_table1("smoke", tmp_path, only=["Random (XL)"], work=tmp_path / "w")
    with pytest.raises(ValueError, match="scale must be"):
        run_table1("huge", tmp_path, work=tmp_path / "w")
