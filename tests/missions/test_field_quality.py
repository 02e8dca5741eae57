"""`uavsearch quality --field`: the masked-fields section on one real field (issue 28: every
command that takes a field takes field.json)."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from missions.cli import app

FIELD = Path(__file__).resolve().parents[2] / "examples" / "fields" / "out" / "pond_meadow" / "field.json"


def test_quality_on_a_real_field_compares_it_with_the_rectangle_of_its_area(tmp_path: Path) -> None:
    r = CliRunner().invoke(app, ["quality", "--field", str(FIELD), "--masked-fields", "12", "--workers", "1",
                                 "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "fields" / "quality_pond_meadow.json").read_text())
    rect, field = doc["table"]["rectangle"], doc["table"]["field pond_meadow"]
    mask = json.loads(FIELD.read_text())
    # every episode on the field's reachable mask, the rectangle of (about) the same searchable
    # area: 542 cells factor only into a 271 x 2 strip, so the nearest square-ish one
    (w, h), area = rect["grid"], doc["config"]["masked_quality"]["area"]
    assert abs(w * h - area) <= max(w, h) and max(w, h) <= 2 * min(w, h), (w, h, area)
    assert field["grid"] == [mask["width"], mask["height"]]
    for cell in (rect, field):
        assert cell["rows"]["oracle"]["ratio"] == 1.0 and cell["rows"]["oracle"]["all_found_pct"] == 100.0
        assert cell["rows"]["belief"]["ratio"] >= 1.0  # the oracle is exact: nothing beats it
    assert doc["git_revision"] and doc["config"]["masked_quality"]["field_name"] == "pond_meadow"
