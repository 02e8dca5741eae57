"""Every file the CLI reads, given something else (a text file, random bytes, an empty file, a
directory, a broken zip, foreign JSON, nothing): one clear line naming the file, a usage exit,
never a traceback (issue 28: `eval --checkpoint /etc/passwd` used to end in an IndexError from
inside torch.load)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from missions.cli import app

runner = CliRunner()

OPTIONS = {
    "dualstream checkpoint": ["eval", "--policy", "dualstream", "--episodes", "5", "--checkpoint"],
    "searchnet checkpoint": ["eval", "--policy", "searchnet", "--episodes", "5", "--checkpoint"],
    "drqn checkpoint": ["eval", "--policy", "drqn", "--episodes", "5", "--checkpoint"],
    "table1 drqn checkpoint": ["table1", "--drqn-checkpoint"],
    "detection table": ["eval", "--policy", "belief", "--episodes", "5", "--levels", "3", "--detection"],
    "polygon field": ["eval", "--policy", "belief", "--episodes", "5", "--field"],
    "quality document": ["quality", "--reuse"],
}


def _bad_files(root: Path) -> dict[str, Path]:
    files = {"text": root / "passwd", "random bytes": root / "random.bin", "empty": root / "empty",
             "directory": root / "adir", "broken zip": root / "broken.zip", "foreign json": root / "other.json"}
    files["text"].write_text("root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1:daemon:/usr/sbin\n")
    files["random bytes"].write_bytes(np.random.default_rng(28).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    files["empty"].write_bytes(b"")
    files["directory"].mkdir()
    files["broken zip"].write_bytes(b"PK\x03\x04" + b"\x00" * 40)
    files["foreign json"].write_text('{"type": "something else", "values": [1, 2, 3]}')
    files["missing"] = root / "no-such-file"
    return files


@pytest.mark.parametrize("option", list(OPTIONS))
def test_a_bad_file_gets_one_line_naming_it(option: str, tmp_path: Path) -> None:
    for kind, path in _bad_files(tmp_path).items():
        r = runner.invoke(app, [*OPTIONS[option], str(path)])
        said = " ".join(r.output.replace("│", " ").split())
        assert r.exit_code != 0, (option, kind, said)
        assert r.exception is None or isinstance(r.exception, SystemExit), (option, kind, repr(r.exception))
        assert "Traceback" not in r.output, (option, kind)
        assert str(path) in said.replace(" ", "") or str(path) in said, (option, kind, said)
