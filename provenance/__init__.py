"""What every file the project writes carries (config, seed, git revision), and how it is
written (to a temporary name, then renamed, so a crash never leaves half a file).
Imported by every package; imports nothing of ours."""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
import time
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Any

__all__ = ["InputFileError", "atomic_open", "atomic_write_bytes", "atomic_write_json", "git_revision", "read_json",
           "stamp"]


class InputFileError(ValueError):
    """A file given to us that cannot be used. `str(e)` is one line, `FILE: what is wrong`, so a
    command prints it as it is and the operator knows which file to fix."""

    def __init__(self, path: object, what: str) -> None:
        self.path = str(path)
        self.what = " ".join(str(what).split())  # one line, whatever a library's message held
        super().__init__(f"{self.path}: {self.what}")


def read_json(path: str | os.PathLike, what: str) -> Any:
    """The JSON in `path` (a `what`: "detection table", "quality document"), or an
    InputFileError saying in one line why not: missing, a directory, not text, empty, not JSON."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputFileError(path, "no such file") from None
    except IsADirectoryError:
        raise InputFileError(path, f"is a directory, not a {what}") from None
    except UnicodeDecodeError:
        raise InputFileError(path, f"is not text (a {what} is JSON)") from None
    except OSError as e:
        raise InputFileError(path, f"cannot be read ({e.strerror})") from None
    if not text.strip():
        raise InputFileError(path, f"is empty (a {what} is JSON)")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise InputFileError(path, f"is not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    except RecursionError:
        raise InputFileError(path, "is not valid JSON (nested too deeply)") from None


@lru_cache(maxsize=1)
def git_revision() -> str:
    """The checkout's commit (with '-dirty' when the tree has changes), or 'unknown'."""
    root = Path(__file__).resolve().parent.parent
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=5
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root, capture_output=True, text=True, timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (rev + ("-dirty" if dirty else "")) if rev else "unknown"


def stamp(config: Any = None, seed: int | None = None, **extra: Any) -> dict[str, Any]:
    """The provenance record: config, seed, git revision, time, plus anything else."""
    return {
        "config": config,
        "seed": seed,
        "git_revision": git_revision(),
        "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        **extra,
    }


@contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb"):
    """Open a temporary file beside `path`; on success fsync and rename it over `path`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results are for everyone to read
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_open(path, "wb") as f:
        f.write(data)


def atomic_write_json(path: str | os.PathLike, obj: Any) -> None:
    with atomic_open(path, "w") as f:
        json.dump(obj, f, indent=2, default=_jsonable)
        f.write("\n")


def _jsonable(o: Any) -> Any:
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


