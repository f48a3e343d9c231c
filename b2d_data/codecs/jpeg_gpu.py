"""JPEG encoding on an NVIDIA GPU through nvJPEG: quality 20 and 4:2:0 chroma, as OpenCV writes them.

nvJPEG scales the standard (IJG) quantisation tables by the quality as libjpeg does, so a file has the same tables
and chroma subsampling as OpenCV's; the pixels decode within codec noise of OpenCV's file (the DCT and the chroma
downsampling filter differ). An encode costs the CPU about 1 ms instead of 4–12 ms, which matters when every core
runs a route. The library is found in the CUDA wheels that PyTorch (a dependency) brings; device memory comes
from PyTorch too. :func:`nvjpeg_encoder` returns ``None`` wherever any of that is missing, and the caller then
encodes with OpenCV.
"""

from __future__ import annotations

import ctypes
import glob
import logging
import os
import sys
import threading

import numpy as np

from b2d_data.codecs._rgba import rgba_parent

log = logging.getLogger(__name__)

_NVJPEG_INPUT_RGBI = 5  # interleaved RGB
_NVJPEG_CSS_420 = 2
_MAX_COMPONENT = 4


class _Image(ctypes.Structure):
    _fields_ = [("channel", ctypes.c_void_p * _MAX_COMPONENT), ("pitch", ctypes.c_size_t * _MAX_COMPONENT)]


def _library_candidates() -> list[str]:
    names = []
    for root in sys.path:
        if root and os.path.isdir(root):
            for pattern in ("nvidia/*/lib/libnvjpeg.so*", "nvidia/*/*/lib/libnvjpeg.so*", "torchvision*/libnvjpeg*.so*",
                            "torch/lib/libnvjpeg*.so*"):  # fmt: skip
                names += sorted(glob.glob(os.path.join(root, pattern)))
    return names + ["libnvjpeg.so", "libnvjpeg.so.13", "libnvjpeg.so.12"]


def _load_library() -> ctypes.CDLL | None:
    for name in _library_candidates():
        try:
            return ctypes.CDLL(name)
        except OSError:
            continue
    return None


class NvJpegEncoder:
    """One nvJPEG handle, encoder state and parameters (quality, 4:2:0) on PyTorch's current CUDA device."""

    def __init__(self, lib: ctypes.CDLL, quality: int) -> None:
        import torch

        self._torch = torch
        self._lib = lib
        self._lock = threading.Lock()
        self.quality = int(quality)
        self._handle, self._state, self._params = ctypes.c_void_p(), ctypes.c_void_p(), ctypes.c_void_p()
        stream = ctypes.c_void_p(0)  # the legacy default stream, which PyTorch's copies also use
        self._stream = stream
        self._check("nvjpegCreateSimple", lib.nvjpegCreateSimple(ctypes.byref(self._handle)))
        self._check("nvjpegEncoderStateCreate",
                    lib.nvjpegEncoderStateCreate(self._handle, ctypes.byref(self._state), stream))  # fmt: skip
        self._check("nvjpegEncoderParamsCreate",
                    lib.nvjpegEncoderParamsCreate(self._handle, ctypes.byref(self._params), stream))  # fmt: skip
        self._check("nvjpegEncoderParamsSetQuality",
                    lib.nvjpegEncoderParamsSetQuality(self._params, ctypes.c_int(self.quality), stream))  # fmt: skip
        self._check("nvjpegEncoderParamsSetSamplingFactors",
                    lib.nvjpegEncoderParamsSetSamplingFactors(self._params, _NVJPEG_CSS_420, stream))  # fmt: skip
        self._check("nvjpegEncoderParamsSetOptimizedHuffman",
                    lib.nvjpegEncoderParamsSetOptimizedHuffman(self._params, 0, stream))  # fmt: skip
        self._device_buffer = torch.empty(0, dtype=torch.uint8, device="cuda")

    @staticmethod
    def _check(call: str, status: int) -> None:
        if status != 0:
            raise RuntimeError(f"{call} failed with nvJPEG status {status}")

    def encode(self, rgb: np.ndarray) -> bytes:
        """Encode an (H, W, 3) uint8 RGB image; the bytes are a baseline JPEG file."""
        torch, lib = self._torch, self._lib
        h, w = rgb.shape[:2]
        rgba = rgba_parent(rgb)
        with self._lock:
            if self._device_buffer.numel() < rgb.nbytes:
                self._device_buffer = torch.empty(rgb.nbytes, dtype=torch.uint8, device="cuda")
            device = self._device_buffer[: rgb.nbytes]
            if rgba is None:
                device.copy_(torch.from_numpy(np.ascontiguousarray(rgb).reshape(-1)))
            else:  # the renderer's RGBA: uploaded whole, the alpha dropped on the GPU rather than by a CPU copy
                device.view(h, w, 3).copy_(torch.from_numpy(rgba).to("cuda")[..., :3])
            image = _Image()
            image.channel[0] = device.data_ptr()
            image.pitch[0] = 3 * w
            self._check("nvjpegEncodeImage", lib.nvjpegEncodeImage(
                self._handle, self._state, self._params, ctypes.byref(image), _NVJPEG_INPUT_RGBI, w, h, self._stream,
            ))  # fmt: skip
            length = ctypes.c_size_t(0)
            self._check("nvjpegEncodeRetrieveBitstream", lib.nvjpegEncodeRetrieveBitstream(
                self._handle, self._state, None, ctypes.byref(length), self._stream))  # fmt: skip
            torch.cuda.current_stream().synchronize()
            out = ctypes.create_string_buffer(length.value)
            self._check("nvjpegEncodeRetrieveBitstream", lib.nvjpegEncodeRetrieveBitstream(
                self._handle, self._state, out, ctypes.byref(length), self._stream))  # fmt: skip
            torch.cuda.current_stream().synchronize()
            return out.raw[: length.value]


_ENCODER: list[NvJpegEncoder | None] = []
#: ``nvjpeg`` encodes on the GPU where an NVIDIA GPU and the library are present; ``opencv`` (the default) never
#: does. With one route process per core sharing one GPU, OpenCV is faster: every process's CUDA context competes
#: for the GPU with the others and with their GL contexts (one H100, 16 route processes: 55.5 frames/s with OpenCV,
#: 47.8 with nvJPEG, same machine and run of ``scripts/bench_collect.py``). nvJPEG pays off for a single process.
ENV_VAR = "B2D_JPEG_ENCODER"


def nvjpeg_encoder(quality: int, *, force: bool = False) -> NvJpegEncoder | None:
    """This process's nvJPEG encoder if ``B2D_JPEG_ENCODER=nvjpeg`` (or ``force``) and it can run, else ``None``."""
    if not force and os.environ.get(ENV_VAR, "opencv").lower() != "nvjpeg":
        return None
    if _ENCODER:
        enc = _ENCODER[0]
        return enc if enc is not None and enc.quality == quality else None
    enc = None
    # Checked before importing PyTorch, which costs a second per process on machines without a GPU.
    if not os.path.isdir("/proc/driver/nvidia/gpus"):
        _ENCODER.append(None)
        return None
    try:
        import torch

        lib = _load_library() if torch.cuda.is_available() else None
        if lib is not None:
            enc = NvJpegEncoder(lib, quality)
            log.info("JPEG images are encoded on the GPU (nvJPEG)")
    except Exception as exc:  # noqa: BLE001 - any failure here means: encode on the CPU
        log.warning("nvJPEG unavailable (%s): JPEG images are encoded by OpenCV", exc)
        enc = None
    _ENCODER.append(enc)
    return enc
