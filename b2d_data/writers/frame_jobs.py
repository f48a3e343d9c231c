"""The encoding work of one frame, split into picklable jobs (one per camera, one for the rest)."""

from __future__ import annotations

import pickle
from dataclasses import dataclass
from typing import Union

import cv2
import numpy as np

from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import write_anno
from b2d_data.codecs.depth import write_depth_npz, write_depth_png
from b2d_data.codecs.expert_npz import write_expert
from b2d_data.codecs.jpeg import write_jpeg, write_jpeg_planes
from b2d_data.codecs.labels_png import write_instance_png, write_semantic_png
from b2d_data.codecs.laz import write_laz
from b2d_data.codecs.radar_h5 import write_radar
from b2d_data.writers.shared_frames import SharedArray, resolve

ArrayArg = Union[np.ndarray, SharedArray]


@dataclass(frozen=True)
class DepthOptions:
    """How float depth npz files are written when the format version asks for them (v0.0.4)."""

    dtype: str = "float32"
    compress: bool = False  # zlib costs ~0.5 s per 1600×900 float image for a 1.4× gain


@dataclass
class CameraJob:
    """Encode and write one camera's RGB (and depth / semantic / instance when present) for one frame."""

    clip_dir: str
    cam: str
    index: int
    rgb: ArrayArg | None
    depth: ArrayArg | None = None
    semantic: ArrayArg | None = None
    instance: ArrayArg | None = None
    float_depth: DepthOptions | None = None  # None: no ``.npz`` next to the depth PNG
    labels: ArrayArg | None = None  # semantic + instance packed as instance-PNG pixels (CameraFrame.labels)
    jpeg_planes: tuple[ArrayArg, ArrayArg, ArrayArg] | None = None  # the image as Y, Cb, Cr (instead of rgb)

    def describe(self) -> str:
        """What the job writes, for error messages."""
        return f"camera {self.cam}"

    def run(self) -> int:
        """Write the files; returns the number of bytes written."""
        clip, i = self.clip_dir, self.index
        rgb_path = layout.image_path(clip, "rgb", self.cam, i)
        if self.jpeg_planes is not None:
            y, cb, cr = (resolve(p) for p in self.jpeg_planes)
            written = write_jpeg_planes(rgb_path, (y, cb, cr))  # type: ignore[arg-type]
        else:
            written = write_jpeg(rgb_path, resolve(self.rgb))
        depth, semantic, instance = resolve(self.depth), resolve(self.semantic), resolve(self.instance)
        if depth is not None:
            written += write_depth_png(layout.image_path(clip, "depth", self.cam, i), depth)
            if self.float_depth is not None:
                written += write_depth_npz(
                    layout.depth_npz_path(clip, self.cam, i), depth,
                    dtype=self.float_depth.dtype, compress=self.float_depth.compress,
                )  # fmt: skip
        if semantic is not None:
            written += write_semantic_png(layout.image_path(clip, "semantic", self.cam, i), semantic)
            if instance is not None:
                written += write_instance_png(layout.image_path(clip, "instance", self.cam, i), semantic, instance,
                                              packed=resolve(self.labels))  # fmt: skip
        return written


@dataclass
class MiscJob:
    """Write one frame's annotation, LiDAR, radar and expert vector."""

    clip_dir: str
    index: int
    anno: dict | bytes  # bytes: the dict pickled when the job was queued
    lidar: ArrayArg | None = None
    radar: dict[str, ArrayArg] | None = None
    expert: ArrayArg | None = None

    def describe(self) -> str:
        """What the job writes, for error messages."""
        return "annotation/lidar/radar/expert"

    def run(self) -> int:
        """Write the files; returns the number of bytes written."""
        clip, i = self.clip_dir, self.index
        # Key orders were checked by the writer before the job was queued.
        anno = pickle.loads(self.anno) if isinstance(self.anno, bytes) else self.anno
        written = write_anno(layout.anno_path(clip, i), anno, frame=f"frame {i}")
        lidar = resolve(self.lidar)
        if lidar is not None:
            written += write_laz(layout.lidar_path(clip, i), lidar)
        if self.radar is not None:
            written += write_radar(layout.radar_path(clip, i), {k: resolve(v) for k, v in self.radar.items()})
        expert = resolve(self.expert)
        if expert is not None:
            written += write_expert(layout.expert_path(clip, i), expert)
        return written


Job = Union[CameraJob, MiscJob]


def run_job(job: Job) -> int:
    """Process-pool entry point: run one job."""
    return job.run()


def init_worker() -> None:
    """Pool initializer: one OpenCV thread per encoding process (the pool itself provides the parallelism)."""
    cv2.setNumThreads(1)
