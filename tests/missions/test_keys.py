"""Signing keys come from a private file, never argv: unsafe files are refused by name."""

import hashlib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from missions.cli import app
from missions.keys import KeyFileError, read_signing_key

runner = CliRunner()


def test_key_file_hex_passphrase_and_unsafe_modes(tmp_path: Path) -> None:
    hexkey = tmp_path / "key.hex"
    hexkey.write_text(bytes(range(32)).hex() + "\n")
    hexkey.chmod(0o600)
    assert read_signing_key(hexkey) == bytes(range(32))
    phrase = tmp_path / "phrase"
    phrase.write_text("correct horse battery staple")
    phrase.chmod(0o400)
    assert read_signing_key(phrase) == hashlib.sha256(b"correct horse battery staple").digest()
    hexkey.chmod(0o644)
    with pytest.raises(KeyFileError, match="chmod 600"):
        read_signing_key(hexkey)
    with pytest.raises(KeyFileError, match="No such file"):
        read_signing_key(tmp_path / "missing")


def test_run_and_sitl_refuse_an_unsafe_key_file_before_anything_starts(tmp_path: Path) -> None:
    key = tmp_path / "key"
    key.write_text("00" * 32)
    key.chmod(0o644)
    for cmd in (["run", "--origin-lat", "51.45", "--origin-lon", "-2.58", "--connect", "udpin:127.0.0.1:14996",
                 "--out", str(tmp_path / "o")], ["sitl", "--duration", "1", "--field-out", str(tmp_path / "f.json")]):
        r = runner.invoke(app, [*cmd, "--signing-key-file", str(key)])
        text = " ".join(r.output.replace("│", " ").split())
        assert r.exit_code == 2 and "chmod 600" in text, (cmd, r.output)


def test_run_refuses_a_bad_connect_address(tmp_path: Path) -> None:
    r = runner.invoke(app, ["run", "--origin-lat", "51.45", "--origin-lon", "-2.58", "--connect", "bogus:xx",
                            "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "bogus:xx" in r.output, r.output
