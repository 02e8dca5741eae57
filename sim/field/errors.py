"""The one error a bad field file raises: a single line naming the file and what is wrong."""

from __future__ import annotations


class FieldError(ValueError):
    """A field file that cannot be read or gridded. `str(e)` is one line: `FILE: what is wrong`,
    so the CLI prints it as it is and an operator knows which file to fix and how."""

    def __init__(self, path: object, what: str) -> None:
        self.path = str(path)
        self.what = " ".join(str(what).split())  # one line, whatever a library's message held
        super().__init__(f"{self.path}: {self.what}")
