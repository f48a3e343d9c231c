"""Shared input handling for the decoders: a path or the encoded bytes, and the name used in errors."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Union

from b2d_data.format.errors import B2DFormatError

#: What every decoder accepts: a file path (``str`` or path-like) or the file's encoded bytes.
Source = Union[str, "os.PathLike[str]", bytes, bytearray, memoryview]

_IN_MEMORY = "<bytes>"


def is_data(source: Source) -> bool:
    """True when ``source`` holds encoded bytes rather than naming a file."""
    return isinstance(source, (bytes, bytearray, memoryview))


def source_name(source: Source, name: str | os.PathLike[str] | None = None) -> Path:
    """The path to name in error messages: ``name`` when given, else the path itself or ``<bytes>``."""
    if name is not None:
        return Path(name)
    if is_data(source):
        return Path(_IN_MEMORY)
    return Path(os.fspath(source))  # type: ignore[arg-type]


def read_source(source: Source, name: str | os.PathLike[str] | None = None) -> tuple[bytes | memoryview, Path]:
    """Return the encoded bytes of ``source`` (reading the file once) and the name for errors."""
    label = source_name(source, name)
    if isinstance(source, (bytes, memoryview)):
        return source, label
    if isinstance(source, bytearray):
        return bytes(source), label
    path = Path(os.fspath(source))  # type: ignore[arg-type]
    try:
        return path.read_bytes(), label
    except FileNotFoundError:
        raise B2DFormatError(label, "file does not exist") from None
    except IsADirectoryError:
        raise B2DFormatError(label, "is a directory, expected a file") from None
    except OSError as exc:
        raise B2DFormatError(label, f"cannot be read: {exc.strerror or exc}") from exc


#: Flags of ``open(path, "wb")``: create or truncate, write only, not inherited by child processes.
_WRITE_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)


def write_bytes(path: str | os.PathLike[str], data: bytes | memoryview) -> int:
    """Write ``data`` to ``path`` and return its size; the parent folder must exist.

    Through the descriptor calls alone: Python's ``open`` adds a stat, a terminal check and a seek to the open,
    write and close of every file, and a collection writes some 30 files a frame through a sandboxed file system.
    """
    view = memoryview(data).cast("B")
    fd = os.open(path, _WRITE_FLAGS, 0o666)
    try:
        done = 0
        while done < len(view):  # a write may take less than it was given (signals, very large buffers)
            done += os.write(fd, view[done:])
    finally:
        os.close(fd)
    return len(view)
