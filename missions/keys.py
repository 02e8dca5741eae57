"""MAVLink 2 signing keys from a file, never from the command line (argv is readable by every
user in /proc). The file holds 64 hex characters (the key) or any other text (a passphrase,
hashed with SHA-256 as MAVProxy's `signing key PASSPHRASE`), and must be private to its owner:
a key file that group or others may read is refused, as ssh refuses such an identity file."""

from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path


class KeyFileError(ValueError):
    """The key file is missing, unsafe, or not a key."""


def read_signing_key(path: Path) -> bytes:
    path = Path(path)
    try:
        st = path.stat()
    except OSError as e:
        raise KeyFileError(f"signing key file {path}: {e.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise KeyFileError(f"signing key file {path} is not a regular file")
    if st.st_mode & 0o077:
        raise KeyFileError(f"signing key file {path} is readable by others (mode {stat.S_IMODE(st.st_mode):o}): "
                           f"chmod 600 {path}")
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        raise KeyFileError(f"signing key file {path} belongs to another user")
    text = path.read_text(encoding="utf-8", errors="strict").strip()
    if not text:
        raise KeyFileError(f"signing key file {path} is empty")
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    return key if len(key) == 32 else hashlib.sha256(text.encode()).digest()
