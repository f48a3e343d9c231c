"""Batching ``ClipDataset`` samples: stack fixed-size fields, list (or pad) variable-size ones, drop skipped frames."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch.utils.data._utils.collate import default_collate_fn_map

#: Fields whose first dimension varies from frame to frame.
VARIABLE_KEYS: frozenset[str] = frozenset({
    "lidar", "radar", "radar_velocity", "radar_sensor",
    "boxes", "box_classes", "box_ids", "box_velocity", "box_num_points", "box_light_state", "box_static",
    "trigger_volumes", "trigger_types", "trigger_light_state", "trigger_affects_ego",
    "map_polylines", "map_types",
})  # fmt: skip
#: Fields kept as plain Python lists (strings, raw annotations, names).
LIST_KEYS: frozenset[str] = frozenset({"clip", "scenario", "town", "camera_names", "anno"})

#: Tensors below this many bytes travel from DataLoader workers by value instead of through shared memory.
BY_VALUE_BYTES = 1 << 16


class _ByValue:
    """A small array that pickles by value (rebuilt as a tensor on unpickling)."""

    __slots__ = ("array",)

    def __init__(self, array: np.ndarray) -> None:
        self.array = array


def _pack(value: Any) -> Any:
    if isinstance(value, torch.Tensor) and value.numel() * value.element_size() < BY_VALUE_BYTES:
        return _ByValue(value.numpy())
    if isinstance(value, list):
        return [_pack(v) for v in value]
    return value


def _unpack(value: Any) -> Any:
    if isinstance(value, _ByValue):
        return torch.from_numpy(value.array)
    if isinstance(value, list):
        return [_unpack(v) for v in value]
    return value


def _rebuild_batch(items: dict[str, Any]) -> Batch:
    return Batch({k: _unpack(v) for k, v in items.items()})


class Batch(dict):
    """A collated batch: a plain dict of tensors, lists and ints.

    Pickling (how DataLoader workers hand batches to the main process) sends tensors under 64 KiB by value:
    torch would give each one its own shared-memory segment, which costs ~0.7 ms apiece and dominated the
    transfer of a sample's ~50 small fields. Large tensors (images, LiDAR) still go through shared memory.
    """

    def __reduce__(self) -> tuple:
        return (_rebuild_batch, ({k: _pack(v) for k, v in self.items()},))


class Ragged(np.ndarray):
    """A sample field whose first dimension varies between frames: a plain ndarray view with its own type.

    Its type tells torch's ``default_collate`` to list such fields instead of stacking them, so that a plain
    ``DataLoader(dataset, batch_size=4)`` works; everything numpy does with it is unchanged.
    """


class RaggedList(list):
    """A per-sample list of arrays of varying count and size (``map_polylines``), listed per sample when batched."""


class RawAnno(dict):
    """The raw annotation dict of a sample (``keep_anno``), listed per sample when batched."""


class Sample(dict):
    """One ``ClipDataset`` sample: a plain dict whose type makes torch's default collate batch it with :func:`collate`.

    torch dispatches on a batch's first element, so a batch of samples, with or without frames skipped with
    ``on_error="skip"`` (their ``BadFrame`` records, also dispatched here), gets the same batch from a plain
    ``DataLoader(dataset, batch_size=...)`` as from :meth:`ClipDataset.loader`.
    """


def _collate_ragged(batch: Sequence[Ragged], *, collate_fn_map: Any = None) -> list[torch.Tensor]:
    return [torch.from_numpy(np.ascontiguousarray(v.view(np.ndarray))) for v in batch]


def _collate_ragged_list(batch: Sequence[RaggedList], *, collate_fn_map: Any = None) -> list[list[torch.Tensor]]:
    return [[torch.from_numpy(np.ascontiguousarray(p)) for p in v] for v in batch]


def _collate_raw(batch: Sequence[RawAnno], *, collate_fn_map: Any = None) -> list[dict]:
    return [dict(v) for v in batch]


def collate_samples(batch: Sequence[Any], *, collate_fn_map: Any = None) -> Batch:
    """torch default-collate hook for a batch of :class:`Sample` and skipped-frame records: :func:`collate`."""
    return collate(batch)


# torch's documented extension point for default_collate (see torch.utils.data.default_collate): these types are
# ours alone, so registering them changes nothing for anyone else's data.
default_collate_fn_map.update(
    {Ragged: _collate_ragged, RaggedList: _collate_ragged_list, RawAnno: _collate_raw, Sample: collate_samples}
)


def mark_variable_fields(sample: dict[str, Any]) -> dict[str, Any]:
    """Tag a sample's variable-size fields (in place) so that torch's default collate lists them; returns it."""
    for key in VARIABLE_KEYS.intersection(sample):
        value = sample[key]
        if key == "map_polylines":
            sample[key] = RaggedList(value)
        elif isinstance(value, np.ndarray):
            sample[key] = value.view(Ragged)
    if isinstance(sample.get("anno"), dict):
        sample["anno"] = RawAnno(sample["anno"])
    return sample


def _tensor(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return torch.from_numpy(np.ascontiguousarray(value))
    if isinstance(value, np.generic):
        return torch.as_tensor(value.item())
    if isinstance(value, list):
        return [_tensor(v) for v in value]
    return value


def _pad(values: list[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
    n = max((len(v) for v in values), default=0)
    first = values[0]
    out = np.zeros((len(values), n) + first.shape[1:], dtype=first.dtype)
    mask = np.zeros((len(values), n), dtype=bool)
    for i, v in enumerate(values):
        out[i, : len(v)] = v
        mask[i, : len(v)] = True
    return torch.from_numpy(out), torch.from_numpy(mask)


def collate(batch: Sequence[Any], pad: bool = False) -> Batch:
    """Batch samples into a dict of tensors.

    Fixed-size arrays are stacked to (B, ...); variable-size fields (:data:`VARIABLE_KEYS`) become lists of
    tensors, or, with ``pad=True``, zero-padded (B, N_max, ...) tensors plus a ``<key>_mask`` (B, N_max) —
    ``map_polylines`` always stays a list of lists. Strings stay lists. Items that are not sample dicts (the
    ``BadFrame`` records of frames skipped with ``on_error="skip"``, or None) are dropped and counted in
    ``skipped``; use ``functools.partial(collate, pad=True)`` as a ``collate_fn`` for padding.
    """
    samples = [s for s in batch if isinstance(s, dict)]
    out = Batch(skipped=len(batch) - len(samples), batch_size=len(samples))
    if not samples:
        return out
    for key in samples[0]:
        values = [s[key] for s in samples]
        if key in LIST_KEYS:
            out[key] = [dict(v) if isinstance(v, RawAnno) else v for v in values]
        elif key == "map_polylines":
            out[key] = _collate_ragged_list(values)
        elif key in VARIABLE_KEYS:
            if pad:
                out[key], out[f"{key}_mask"] = _pad([np.asarray(v).view(np.ndarray) for v in values])
            else:
                out[key] = [_tensor(np.asarray(v).view(np.ndarray)) for v in values]
        elif isinstance(values[0], np.ndarray) and all(
            isinstance(v, np.ndarray) and v.shape == values[0].shape for v in values
        ):
            out[key] = torch.from_numpy(np.stack(values))
        elif isinstance(values[0], (np.generic, int, float, bool)):
            out[key] = torch.as_tensor(np.array(values))
        else:
            # Per-camera lists of differently sized images, or other ragged values.
            out[key] = [_tensor(v) for v in values]
    return out
