"""`uavsearch field` end to end on a committed example, and a bad file's one line."""

from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from missions.cli import app
from sim.field import FORBIDDEN, load_field

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "fields"
runner = CliRunner()


def test_field_command_writes_json_and_png(tmp_path: Path) -> None:
    r = runner.invoke(app, ["field", str(EXAMPLES / "pond_meadow.kml"), "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "KML: Placemark 'Pond meadow'" in r.output
    assert "grid 27 x 24 = 648 cells of 2 m at heading -2.15 deg (the minimum-area rectangle's)" in r.output
    assert "searchable 542 cells (83.6 %), masked 16.4 %: outside 54, forbidden 52" in r.output
    f = load_field(tmp_path / "field.json")
    assert f.searchable_cells == 542 and f.no_fly[0].kind == "hole" and (f.classes == FORBIDDEN).sum() == 52
    assert (tmp_path / "field.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the committed output is what the command makes today
    committed = load_field(EXAMPLES / "out" / "pond_meadow" / "field.json")
    assert np.array_equal(committed.classes, f.classes) and committed.origin == f.origin
    r = runner.invoke(app, ["field", str(EXAMPLES / "l_paddock_30deg.geojson"), "--heading", "0",
                            "--cell-m", "4", "--out", str(tmp_path / "n")])
    assert r.exit_code == 0 and "at heading 0.00 deg (given)" in r.output


def test_field_command_bad_file_is_one_line(tmp_path: Path) -> None:
    p = tmp_path / "bowtie.plan"
    p.write_text('{"fileType": "Plan", "geoFence": {"polygons": [{"inclusion": true, "polygon": '
                 '[[51.4545, -2.5879], [51.4548, -2.5875], [51.4548, -2.5879], [51.4545, -2.5875]]}]}}')
    r = runner.invoke(app, ["field", str(p), "--out", str(tmp_path / "o")])
    assert r.exit_code == 1 and "Traceback" not in r.output
    assert r.output.strip().count("\n") == 0
    assert r.output.startswith(f"error: {p}: geoFence polygon 0 ring crosses itself near 51.4546")
    assert not (tmp_path / "o").exists()
