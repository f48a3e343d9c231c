"""Exceptions for files that do not follow the Bench2Drive format."""

from __future__ import annotations

from pathlib import Path


class B2DFormatError(ValueError):
    """A file that is missing, truncated or not in the expected encoding; the message names the file."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
