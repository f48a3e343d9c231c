"""Tags and ids as views of one packed label image, and the instance PNG encoded straight from it."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.codecs.labels_png import encode_instance_png, read_instance_png
from b2d_data.format.label_pixels import label_views


def _packed() -> np.ndarray:
    packed = np.zeros((2, 3, 4), np.uint8)
    packed[..., 3] = 255
    packed[0, 1] = (7, 0x34, 0x12, 255)  # tag 7, id 0x1234 = 4660
    packed[1, 2] = (14, 0xFF, 0x00, 255)  # tag 14, id 255
    return packed


def test_views_read_tag_and_little_endian_id():
    packed = _packed()
    tags, ids = label_views(packed)
    assert tags.dtype == np.uint8 and ids.dtype == np.uint16 and tags.shape == ids.shape == (2, 3)
    np.testing.assert_array_equal(tags, [[0, 7, 0], [0, 0, 14]])
    np.testing.assert_array_equal(ids, [[0, 4660, 0], [0, 0, 255]])
    packed[0, 0, 2] = 1  # the views share the memory: high byte 1 → id 256
    assert ids[0, 0] == 256


def test_instance_png_from_views_is_the_file_from_planes():
    packed = _packed()
    tags, ids = label_views(packed)
    data = encode_instance_png(tags, ids, packed=packed)
    assert data == encode_instance_png(tags.copy(), ids.copy())
    got_tags, got_ids = read_instance_png(data)
    np.testing.assert_array_equal(got_tags, tags)
    np.testing.assert_array_equal(got_ids, ids)


def test_views_of_rows_that_lie_apart():
    """Rows one byte apart (the renderer's PNG scanlines): the same tags and ids, still views."""
    packed = _packed()
    lines = np.zeros((2, 13), np.uint8)
    lines[:, 1:] = packed.reshape(2, 12)
    spaced = lines[:, 1:].reshape(2, 3, 4)
    tags, ids = label_views(spaced)
    np.testing.assert_array_equal(tags, [[0, 7, 0], [0, 0, 14]])
    np.testing.assert_array_equal(ids, [[0, 4660, 0], [0, 0, 255]])
    lines[1, 1 + 4 * 2 + 2] = 2  # row 1, pixel 2, high byte: id 255 + 2 * 256
    assert ids[1, 2] == 767
    with pytest.raises(ValueError, match="contiguous rows"):
        label_views(packed[:, ::2])  # pixels apart within a row
