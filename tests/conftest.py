"""Suite-wide settings.

Rich wraps the CLI's error boxes at the terminal's width, and a test reading an error's words
must not depend on how long its temporary path is (pytest-xdist's workers add `popen-gwN/` to
every tmp_path): during each test the CLI's console is wide."""

import pytest


@pytest.fixture(autouse=True)
def _wide_console(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "240")
