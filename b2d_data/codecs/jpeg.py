"""RGB camera images as OpenCV JPEG at quality 20 (format.md §2.1): RGB in memory, BGR on disk."""

from __future__ import annotations

import os

import cv2
import numpy as np

from b2d_data.codecs._rgba import rgba_parent
from b2d_data.codecs._source import Source, read_source, write_bytes
from b2d_data.codecs.jpeg_gpu import nvjpeg_encoder
from b2d_data.format.errors import B2DFormatError

#: Bench2Drive's collector writes every camera image at this JPEG quality; nothing else is changed.
JPEG_QUALITY = 20

_SOI = b"\xff\xd8"
_EOI = b"\xff\xd9"
_REDUCED = {
    1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4, 8: cv2.IMREAD_REDUCED_COLOR_8,
}  # fmt: skip


def _check_rgb(rgb: np.ndarray) -> None:
    if not isinstance(rgb, np.ndarray) or rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        got = f"{rgb.dtype} {rgb.shape}" if isinstance(rgb, np.ndarray) else type(rgb).__name__
        raise ValueError(f"RGB image must be a (H, W, 3) uint8 array, got {got}")


def encode_jpeg(rgb: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """Encode an (H, W, 3) uint8 RGB image as OpenCV does in Bench2Drive (quality 20, 4:2:0, baseline).

    ``B2D_JPEG_ENCODER=nvjpeg`` encodes on an NVIDIA GPU instead (``jpeg_gpu``: same quantisation tables and
    subsampling, decoded within codec noise of OpenCV's file), which pays off only for a single route process.
    """
    _check_rgb(rgb)
    gpu = nvjpeg_encoder(int(quality))
    if gpu is not None:
        return gpu.encode(rgb)
    return encode_jpeg_opencv(rgb, quality)


def encode_jpeg_opencv(rgb: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """Encode with OpenCV on the CPU (BGR, the given quality, OpenCV's defaults otherwise)."""
    _check_rgb(rgb)
    rgba = rgba_parent(rgb)
    bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR) if rgba is None else cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGR)
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {rgb.shape} image as JPEG")
    return buf.tobytes()


def write_jpeg(path: str | os.PathLike[str], rgb: np.ndarray, quality: int = JPEG_QUALITY) -> int:
    """Write ``rgb`` as a quality-20 JPEG file; returns the number of bytes written."""
    return write_bytes(path, encode_jpeg(rgb, quality))


def _ends_with_eoi(data: bytes | memoryview) -> bool:
    # Some encoders pad after EOI; OpenCV does not, but a few zero bytes must not make a good file "truncated".
    tail = bytes(data[-64:]).rstrip(b"\x00")
    return tail.endswith(_EOI)


def read_jpeg(source: Source, *, reduce: int = 1, name: str | os.PathLike[str] | None = None) -> np.ndarray:
    """Decode a JPEG (path or bytes) to (H, W, 3) uint8 RGB; ``reduce`` ∈ {1, 2, 4, 8} decodes at 1/reduce size.

    A file that is not a JPEG, lacks its end-of-image marker (truncated) or that OpenCV cannot decode raises
    ``B2DFormatError`` naming it; OpenCV alone would return a partially grey image for a truncated file.
    """
    if reduce not in _REDUCED:
        raise ValueError(f"reduce must be one of {sorted(_REDUCED)}, got {reduce}")
    data, label = read_source(source, name)
    if len(data) < 4 or bytes(data[:2]) != _SOI:
        raise B2DFormatError(label, "not a JPEG file (missing the FF D8 start-of-image marker)")
    if not _ends_with_eoi(data):
        raise B2DFormatError(label, "truncated JPEG (missing the FF D9 end-of-image marker)")
    bgr = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), _REDUCED[reduce])
    if bgr is None:
        raise B2DFormatError(label, "corrupt JPEG: OpenCV could not decode it")
    if bgr.ndim == 2:  # a grayscale JPEG decodes to one channel with some builds; serve it as RGB anyway
        return cv2.cvtColor(bgr, cv2.COLOR_GRAY2RGB)
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def read_quantization_tables(source: Source, *, name: str | os.PathLike[str] | None = None) -> dict[int, np.ndarray]:
    """The JPEG's quantisation tables by table id, each 64 values in zig-zag order (to check the quality)."""
    data, label = read_source(source, name)
    raw = bytes(data)
    tables: dict[int, np.ndarray] = {}
    pos = 2
    while pos + 4 <= len(raw):
        if raw[pos] != 0xFF:
            raise B2DFormatError(label, f"corrupt JPEG: expected a marker at byte {pos}")
        marker = raw[pos + 1]
        if marker == 0xDA:  # start of scan: every table comes before it
            break
        length = int.from_bytes(raw[pos + 2 : pos + 4], "big")
        if marker == 0xDB:
            seg, i = raw[pos + 4 : pos + 2 + length], 0
            while i < len(seg):
                precision, table_id = seg[i] >> 4, seg[i] & 0x0F
                width = 2 if precision else 1
                body = seg[i + 1 : i + 1 + 64 * width]
                tables[table_id] = np.frombuffer(body, dtype=">u2" if width == 2 else np.uint8).astype(np.int32)
                i += 1 + 64 * width
        pos += 2 + length
    if not tables:
        raise B2DFormatError(label, "no quantisation table before the first scan: not a baseline JPEG")
    return tables
