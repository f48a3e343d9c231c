"""Reading a pickled object array from an npz without running code from the file.

Bench2Drive's HD maps are ``np.savez`` archives of object arrays, i.e. pickles. ``np.load(allow_pickle=True)``
lets a pickle call any importable function, so a map from a downloaded corpus could run code. Here the pickle
is read by an unpickler that admits only the globals a numpy array of plain Python data needs (the ndarray
reconstructor, ``ndarray``, ``dtype`` and numpy scalars); lists, dicts, tuples, strings, numbers, booleans and
None need no global at all. Any other global is refused before it is looked up.
"""

from __future__ import annotations

import pickle
import zipfile
from pathlib import Path
from typing import IO, Any

import numpy as np

from b2d_data.format.errors import B2DFormatError

# Taken from numpy's own pickling so that both numpy 1.x (numpy.core) and 2.x (numpy._core) names resolve to
# the functions this numpy uses.
_RECONSTRUCT = np.empty(0).__reduce__()[0]
_SCALAR = np.float64(0.0).__reduce__()[0]

#: (module, name) of every global an object-array pickle of plain data may name, and what it resolves to.
ALLOWED_GLOBALS: dict[tuple[str, str], Any] = {
    ("numpy", "ndarray"): np.ndarray,
    ("numpy", "dtype"): np.dtype,
    ("numpy.core.multiarray", "_reconstruct"): _RECONSTRUCT,
    ("numpy._core.multiarray", "_reconstruct"): _RECONSTRUCT,
    ("numpy.core.multiarray", "scalar"): _SCALAR,
    ("numpy._core.multiarray", "scalar"): _SCALAR,
}


class RefusedGlobalError(pickle.UnpicklingError):
    """A pickle names a global outside :data:`ALLOWED_GLOBALS`."""

    def __init__(self, module: str, name: str) -> None:
        self.qualname = f"{module}.{name}"
        super().__init__(self.qualname)


class _PlainDataUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        try:
            return ALLOWED_GLOBALS[(module, name)]
        except KeyError:
            raise RefusedGlobalError(module, name) from None

    def persistent_load(self, pid: Any) -> Any:
        raise pickle.UnpicklingError("persistent ids are not allowed")


def _read_npy(member: IO[bytes], label: Path) -> np.ndarray:
    version = np.lib.format.read_magic(member)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(member)
    elif version == (2, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(member)
    else:
        raise B2DFormatError(label, f"unsupported .npy format version {version[0]}.{version[1]}")
    if not dtype.hasobject:
        data = np.frombuffer(member.read(), dtype=dtype, count=int(np.prod(shape, dtype=np.int64)))
        return data.reshape(shape, order="F" if fortran else "C").copy()
    try:
        array = _PlainDataUnpickler(member).load()
    except RefusedGlobalError as exc:
        raise B2DFormatError(
            label,
            f"refused to unpickle '{exc.qualname}': this file may try to run code; only numpy arrays, lists, "
            "dicts, tuples, strings, numbers and None are read from a pickled array",
        ) from None
    if not isinstance(array, np.ndarray):
        raise B2DFormatError(label, f"pickled object is a {type(array).__name__}, not a numpy array")
    return array


def load_object_npz(path: str | Path, key: str) -> np.ndarray:
    """Array ``key`` of the npz at ``path``, object arrays included, without running code; errors name the file."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            names = [n.removesuffix(".npy") for n in archive.namelist()]
            if key not in names:
                raise B2DFormatError(path, f"npz has no '{key}' array (has {names})")
            with archive.open(f"{key}.npy") as member:
                return _read_npy(member, path)
    except FileNotFoundError:
        raise B2DFormatError(path, "file does not exist") from None
    except B2DFormatError:
        raise
    except Exception as exc:  # zip, header and pickle errors all mean an unreadable npz
        raise B2DFormatError(path, f"not a readable npz: {exc}") from exc
