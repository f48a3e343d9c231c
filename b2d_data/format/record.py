"""In-memory records handed from the data agent to the clip writer: one per 10 Hz frame."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class CameraFrame:
    """One camera's images at one frame.

    ``rgb`` is (H, W, 3) uint8 in **RGB** order. The dense labels exist for the six surround cameras only:
    ``depth`` (H, W) float32 metres (linear, along the optical axis; or uint8 metres already rounded as the depth
    PNG stores them, when only the PNG is written), ``semantic`` (H, W) uint8 CARLA tag
    ids, ``instance`` (H, W) uint16 object ids (0 = none; low/high byte go to the G/B channels on disk).
    ``labels``, when the renderer packed them, is the (H, W, 4) uint8 instance-PNG image of the same tags and ids
    (``format.label_pixels``): the writer encodes it as it is instead of assembling it again.
    ``jpeg_planes``, when the renderer converted the colour on the GPU, is the image as the JPEG's Y (H, W), Cb and
    Cr (H/2, W/2) uint8 planes (``codecs.jpeg.jpeg_planes``), and ``rgb`` is None.
    """

    rgb: np.ndarray | None
    depth: np.ndarray | None = None
    semantic: np.ndarray | None = None
    instance: np.ndarray | None = None
    labels: np.ndarray | None = None
    jpeg_planes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def size(self) -> tuple[int, int]:
        """(height, width) of the image, from whichever form it has."""
        if self.rgb is not None:
            return self.rgb.shape[0], self.rgb.shape[1]
        if self.jpeg_planes is None:
            raise ValueError("camera frame has neither rgb nor jpeg_planes")
        return self.jpeg_planes[0].shape[0], self.jpeg_planes[0].shape[1]


@dataclass
class FrameRecord:
    """Everything written for one frame of a clip.

    ``anno`` is the complete annotation dict in Bench2Drive's key order (format.md §3). ``cameras`` is keyed
    by camera folder name (``front`` … ``back_right``, ``top_down``). ``lidar`` is (N, 3) float in the
    left-handed CARLA **ego** frame, as stored in the LAZ files. ``radar`` maps the h5 dataset names
    (``radar_front`` …) to (N, 4) arrays [depth m, altitude rad, azimuth rad, velocity m/s].
    ``expert_assessment`` is the optional expert vector stored at index ``frame − 1`` (feature ‖ value ‖ action
    index; the data agent writes the layout of :mod:`b2d_data.format.expert_feature`).
    """

    index: int
    anno: dict
    cameras: dict[str, CameraFrame] = field(default_factory=dict)
    lidar: np.ndarray | None = None
    radar: dict[str, np.ndarray] | None = None
    expert_assessment: np.ndarray | None = None
