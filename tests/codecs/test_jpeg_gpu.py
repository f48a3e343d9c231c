"""nvJPEG encoding (machines with an NVIDIA GPU only): the same JPEG as OpenCV's, within codec noise."""

from __future__ import annotations

import io

import cv2
import numpy as np
import pytest
from PIL import Image

from b2d_data.codecs.jpeg import JPEG_QUALITY, encode_jpeg_opencv, read_jpeg, read_quantization_tables
from b2d_data.codecs.jpeg_gpu import nvjpeg_encoder

encoder = nvjpeg_encoder(JPEG_QUALITY, force=True)
pytestmark = pytest.mark.skipif(encoder is None, reason="no NVIDIA GPU with nvJPEG here")


def _sampling(data: bytes) -> list[tuple[int, int]]:
    """(horizontal, vertical) sampling factors of each component, from the baseline frame header (SOF0)."""
    pos = 2
    while pos < len(data):
        marker, length = data[pos + 1], int.from_bytes(data[pos + 2 : pos + 4], "big")
        if marker == 0xC0:
            count = data[pos + 9]
            return [(data[pos + 11 + 3 * k] >> 4, data[pos + 11 + 3 * k] & 15) for k in range(count)]
        pos += 2 + length
    raise AssertionError("no SOF0 marker: not a baseline JPEG")


def _scene(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.integers(0, 256, (450, 800, 3), dtype=np.uint8), (9, 9), 3)
    img[225:] = (90, 90, 95)
    img[300:340, 100:300] = (200, 30, 30)
    return np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(255.0**2 / np.mean((a.astype(float) - b.astype(float)) ** 2)))


def test_same_tables_and_subsampling_as_opencv():
    img = _scene(0)
    gpu, cpu = encoder.encode(img), encode_jpeg_opencv(img)
    tables_gpu, tables_cpu = read_quantization_tables(gpu), read_quantization_tables(cpu)
    assert tables_gpu.keys() == tables_cpu.keys()
    for key in tables_cpu:
        assert np.array_equal(tables_gpu[key], tables_cpu[key])
    assert _sampling(gpu) == _sampling(cpu) == [(2, 2), (1, 1), (1, 1)]  # 4:2:0


def test_rgb_view_of_rgba_is_uploaded_whole():
    img = _scene(3)
    rgba = np.dstack([img, np.full(img.shape[:2], 255, np.uint8)])
    assert encoder.encode(rgba[..., :3]) == encoder.encode(np.ascontiguousarray(img))


def test_decoded_within_codec_noise_of_opencv():
    for seed in range(3):
        img = _scene(seed)
        gpu, cpu = encoder.encode(img), encode_jpeg_opencv(img)
        via_cv, reference = read_jpeg(gpu), read_jpeg(cpu)
        via_pil = np.asarray(Image.open(io.BytesIO(gpu)).convert("RGB"))
        assert via_cv.shape == via_pil.shape == img.shape
        # Both encoders lose about as much: PSNR against the source within 1 dB of each other.
        assert abs(_psnr(via_cv, img) - _psnr(reference, img)) < 1.0
        # And the two decodes are closer to each other than either is to the source.
        assert _psnr(via_cv, reference) > min(_psnr(via_cv, img), _psnr(reference, img))
        assert 0.5 < len(gpu) / len(cpu) < 2.0
