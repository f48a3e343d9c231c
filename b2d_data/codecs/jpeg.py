"""RGB camera images as OpenCV JPEG at quality 20 (format.md §2.1): RGB in memory, BGR on disk."""

from __future__ import annotations

import os

import cv2
import numpy as np
import simplejpeg

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


#: libjpeg's RGB -> YCbCr constants (jccolor.c): round(coefficient * 2**16).
_Y = (19595, 38470, 7471)
_CB = (-11059, -21709, 32768)
_CR = (32768, -27439, -5329)
_HALF = 1 << 15
_CBCR_OFFSET = 128 << 16


def jpeg_planes(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Y, Cb, Cr planes (4:2:0) libjpeg derives from ``rgb`` before the DCT; even width and height only.

    Integer arithmetic as libjpeg does it: each component is rounded from 16-bit fixed point (Cb/Cr round half
    down), and each chroma sample is the sum of its 2×2 block plus a bias of 1 and 2 on alternate columns, over 4.
    The renderer computes the same planes on the GPU (``shaders.PLANES_COMPUTE``); this is the reference.
    """
    _check_rgb(rgb)
    h, w = rgb.shape[:2]
    if h % 2 or w % 2:
        raise ValueError(f"4:2:0 planes need an even width and height, got {w}x{h}")
    r, g, b = (rgb[..., k].astype(np.int32) for k in range(3))
    y = (_Y[0] * r + _Y[1] * g + _Y[2] * b + _HALF) >> 16
    cb = (_CB[0] * r + _CB[1] * g + _CB[2] * b + _CBCR_OFFSET + _HALF - 1) >> 16
    cr = (_CR[0] * r + _CR[1] * g + _CR[2] * b + _CBCR_OFFSET + _HALF - 1) >> 16
    bias = np.where(np.arange(w // 2) % 2 == 0, 1, 2)

    def down(c: np.ndarray) -> np.ndarray:
        return ((c.reshape(h // 2, 2, w // 2, 2).sum(axis=(1, 3)) + bias) >> 2).astype(np.uint8)

    return y.astype(np.uint8), down(cb), down(cr)


def check_jpeg_planes(planes: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    """Raise ValueError unless ``planes`` are uint8 Y (H, W), Cb and Cr (H/2, W/2) with even H and W."""
    y, cb, cr = planes
    if not all(isinstance(p, np.ndarray) and p.dtype == np.uint8 and p.ndim == 2 for p in planes):
        raise ValueError("JPEG planes must be three 2-D uint8 arrays (Y, Cb, Cr)")
    h, w = y.shape
    if h % 2 or w % 2 or cb.shape != (h // 2, w // 2) or cr.shape != cb.shape:
        raise ValueError(f"4:2:0 planes must be Y (H, W) with even H, W and Cb, Cr (H/2, W/2); got "
                         f"{y.shape}, {cb.shape}, {cr.shape}")  # fmt: skip


def encode_jpeg_planes(planes: tuple[np.ndarray, np.ndarray, np.ndarray], quality: int = JPEG_QUALITY) -> bytes:
    """Encode 4:2:0 Y, Cb, Cr planes (``jpeg_planes``) as a baseline JPEG with libjpeg-turbo, skipping its colour
    conversion. Same quantisation tables, subsampling and headers as OpenCV's file of the RGB image; the scan is often
    byte-identical (7 of 12 rendered 1600×900 frames) and otherwise within codec noise (the libjpeg-turbo builds
    round a few DCT coefficients differently; the error to the image is the same to three digits)."""
    check_jpeg_planes(planes)
    y, cb, cr = (np.ascontiguousarray(p) for p in planes)
    return simplejpeg.encode_jpeg_yuv_planes(y, cb, cr, quality=int(quality))


def write_jpeg_planes(
    path: str | os.PathLike[str], planes: tuple[np.ndarray, np.ndarray, np.ndarray], quality: int = JPEG_QUALITY
) -> int:
    """Write 4:2:0 planes as a quality-20 JPEG file; returns the number of bytes written."""
    return write_bytes(path, encode_jpeg_planes(planes, quality))


def planes_to_rgb(planes: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """(H, W, 3) uint8 RGB of 4:2:0 planes (chroma upsampled by OpenCV; for previews, not bit-exact work)."""
    check_jpeg_planes(planes)
    y, cb, cr = planes
    size = (y.shape[1], y.shape[0])
    up = [cv2.resize(c, size, interpolation=cv2.INTER_LINEAR) for c in (cr, cb)]
    return cv2.cvtColor(np.dstack([y, *up]), cv2.COLOR_YCrCb2RGB)  # OpenCV's YCrCb is JPEG's full range


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
