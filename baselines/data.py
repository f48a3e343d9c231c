"""Training tensors from a corpus: one pass of a plain ``DataLoader`` over ``ClipDataset``, cached on disk.

The pass reads each frame once through the project's loader (every coordinate fix applied there); later epochs and
resumed runs train from the cached tensors, which is what makes an AD-MLP epoch take a second on a laptop CPU and
a TCP epoch on a GPU run at the GPU's pace instead of the JPEG decoder's.
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import DataLoader

from b2d_data import ClipDataset
from b2d_data.loaders.dataset import worker_init_fn
from b2d_data.splits import CORPUS_SPLITS_DIR

from baselines.features import TCP_SPEED_SCALE, command_one_hot

logger = logging.getLogger(__name__)

#: Key of the collected camera size (height, width) among the extracted tensors (not a per-frame field).
CAMERA_HW = "camera_hw"

#: Per-frame fields each model needs from ``ClipDataset`` (CARLA ego frame, poses as the agent sees them).
_COMMON = {"lidar": False, "boxes": False, "frame": "carla", "pose_source": "gnss", "past_steps": 4}


def dataset_options(model: str, future_steps: int) -> dict[str, Any]:
    """``ClipDataset`` keyword options for ``admlp`` or ``tcp``."""
    if model == "admlp":
        return {**_COMMON, "cameras": (), "future_steps": future_steps}
    if model == "tcp":
        return {**_COMMON, "cameras": ("front",), "expert": True, "future_steps": future_steps}
    raise ValueError(f"unknown model {model!r}; use admlp or tcp")


def has_split(root: Path) -> bool:
    """Whether the corpus holds its own split manifest (``b2d-collect --preset`` writes one)."""
    return len(list((root / CORPUS_SPLITS_DIR).glob("*.json"))) == 1


def open_dataset(root: Path, model: str, future_steps: int, part: str) -> ClipDataset:
    """The corpus (``part`` ``all``) or one part of its own split manifest, with the model's fields."""
    split = part if part in ("train", "val") else None
    return ClipDataset(root, split=split, index="update", **dataset_options(model, future_steps))


def commands_one_hot(commands: torch.Tensor) -> torch.Tensor:
    """(B,) RoadOption values → (B, 6) one-hot, through :func:`command_one_hot` (the agents' function)."""
    return torch.from_numpy(np.stack([command_one_hot(int(c)) for c in commands.tolist()]))


def admlp_inputs(batch: dict) -> torch.Tensor:
    """(B, 22) AD-MLP inputs from a collated batch; the same layout as :func:`baselines.features.admlp_input`."""
    b = batch["ego_speed"].shape[0]
    return torch.cat(
        [
            batch["past_waypoints"].reshape(b, -1).float(),
            batch["past_yaw"].reshape(b, -1).float(),
            batch["ego_speed"].reshape(b, 1).float(),
            batch["ego_accel"].reshape(b, 3).float(),
            commands_one_hot(batch["command"]),
        ],
        dim=1,
    )


def tcp_states(batch: dict) -> torch.Tensor:
    """(B, 9) TCP measurements from a batch; the layout of :func:`baselines.features.tcp_state`."""
    b = batch["ego_speed"].shape[0]
    target = torch.nan_to_num(batch["target_point"].float())
    speed = batch["ego_speed"].reshape(b, 1).float() / TCP_SPEED_SCALE
    return torch.cat([speed, target, commands_one_hot(batch["command"])], dim=1)


def _resize_uint8(images: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """(B, H, W, 3) uint8 → (B, height, width, 3) uint8 (antialiased bilinear), a no-op at that size already."""
    if images.shape[1] == height and images.shape[2] == width:
        return images.contiguous()
    x = images.permute(0, 3, 1, 2).float()
    x = torch.nn.functional.interpolate(x, size=(height, width), mode="bilinear", align_corners=False, antialias=True)
    return x.round().clamp(0, 255).to(torch.uint8).permute(0, 2, 3, 1).contiguous()


def extract(
    ds: ClipDataset, model: str, image_size: tuple[int, int] | None, batch_size: int = 64, workers: int = 0
) -> dict[str, torch.Tensor]:
    """One pass of a plain ``DataLoader`` over ``ds``: the model's inputs and targets for every frame."""
    loader = DataLoader(
        ds, batch_size=batch_size, shuffle=False, num_workers=workers,
        worker_init_fn=worker_init_fn if workers else None,
    )  # fmt: skip
    parts: dict[str, list[torch.Tensor]] = {}
    start, seen = time.monotonic(), 0
    camera_hw: tuple[int, int] | None = None
    for batch in loader:
        if not batch.get("batch_size", 1):
            continue
        item: dict[str, torch.Tensor] = {
            "future_wp": batch["future_waypoints"].float(),
            "future_yaw": batch["future_yaw"].float(),
            "future_valid": batch["future_valid"].bool(),
            "speed": batch["ego_speed"].float(),
        }
        if model == "admlp":
            item["input"] = admlp_inputs(batch)
        else:
            assert image_size is not None
            item["state"] = tcp_states(batch)
            item["target_point"] = torch.nan_to_num(batch["target_point"].float())
            camera_hw = camera_hw or (int(batch["images"].shape[2]), int(batch["images"].shape[3]))
            item["images"] = _resize_uint8(batch["images"][:, 0], *image_size)
            item["action"] = batch["expert_action"].long()
            item["feature"] = batch["expert_feature"].float()
        for key, value in item.items():
            parts.setdefault(key, []).append(value)
        seen += int(batch["ego_speed"].shape[0])
    logger.info("read %d frames in %.1f s", seen, time.monotonic() - start)
    out = {k: torch.cat(v) for k, v in parts.items()}
    if camera_hw is not None:
        out[CAMERA_HW] = torch.tensor(camera_hw)  # the collected size: the TCP agent mounts its camera at it
    return out


def cache_key(root: Path, ds: ClipDataset, model: str, extra: dict) -> str:
    """A short hash of what the cache holds: corpus, clips, frame count, model fields."""
    blob = json.dumps(
        {"root": str(root.resolve()), "clips": ds.clip_names, "n": len(ds), "model": model, **extra}, sort_keys=True
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def load_or_extract(
    root: Path,
    model: str,
    part: str,
    future_steps: int,
    cache_dir: Path,
    image_size: tuple[int, int] | None = None,
    workers: int = 0,
) -> dict[str, torch.Tensor]:
    """The cached tensors of ``part`` of the corpus, extracting (and saving) them on first use."""
    ds = open_dataset(root, model, future_steps, part)
    key = cache_key(root, ds, model, {"future_steps": future_steps, "image_size": image_size, "part": part})
    path = cache_dir / f"cache_{model}_{part}_{key}.pt"
    if path.is_file():
        logger.info("using cached tensors %s", path)
        return torch.load(path)
    if len(ds) == 0:
        raise ValueError(f"{root}: no frames for part {part!r}")
    logger.info("extracting %d frames of %d clips (%s) from %s", len(ds), len(ds.clip_names), part, root)
    data = extract(ds, model, image_size, workers=workers)
    cache_dir.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    torch.save(data, tmp)
    tmp.replace(path)
    return data
