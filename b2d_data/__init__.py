"""b2d-data: generate, store, load and evaluate driving data in the Bench2Drive format."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

if TYPE_CHECKING:
    from b2d_data.loaders import ClipDataset


def __getattr__(name: str) -> Any:
    # Importing torch costs ~1 s; only pay for it when the dataset is asked for.
    if name == "ClipDataset":
        from b2d_data.loaders import ClipDataset

        return ClipDataset
    raise AttributeError(f"module 'b2d_data' has no attribute {name!r}")
