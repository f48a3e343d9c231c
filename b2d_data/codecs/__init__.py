"""Every on-disk encoding of a Bench2Drive clip, each module with its encoder and exact inverse.

Decoders take a path or the encoded bytes and raise ``b2d_data.format.errors.B2DFormatError`` naming the file.
"""

from b2d_data.codecs import layout
from b2d_data.codecs.anno_json import (
    AnnoSchemaError,
    anno_text,
    encode_anno,
    read_anno,
    validate_anno,
    write_anno,
)
from b2d_data.codecs.depth import (
    DEPTH_NPZ_KEY,
    depth_to_png_pixels,
    encode_depth_npz,
    encode_depth_png,
    read_depth_npz,
    read_depth_png,
    write_depth_npz,
    write_depth_png,
)
from b2d_data.codecs.expert_npz import (
    EXPERT_NPZ_KEY,
    encode_expert,
    expert_file_name,
    expert_frame_index,
    read_expert,
    split_expert,
    write_expert,
)
from b2d_data.codecs.format_info import CameraInfo, ClipFormatInfo, read_format_info, write_format_info
from b2d_data.codecs.jpeg import JPEG_QUALITY, encode_jpeg, read_jpeg, read_quantization_tables, write_jpeg
from b2d_data.codecs.labels_png import (
    encode_instance_png,
    encode_semantic_png,
    instance_bgra,
    instance_rgba,
    read_instance_png,
    read_semantic_png,
    split_instance,
    write_instance_png,
    write_semantic_png,
)
from b2d_data.codecs.laz import LAZ_SCALE, encode_laz, read_laz, write_laz
from b2d_data.codecs.radar_h5 import RADAR_COLUMNS, RADAR_DATASETS, encode_radar, read_radar, write_radar

__all__ = [
    "DEPTH_NPZ_KEY", "EXPERT_NPZ_KEY", "JPEG_QUALITY", "LAZ_SCALE", "RADAR_COLUMNS", "RADAR_DATASETS",
    "AnnoSchemaError", "CameraInfo", "ClipFormatInfo",
    "anno_text", "depth_to_png_pixels", "encode_anno", "encode_depth_npz", "encode_depth_png", "encode_expert",
    "encode_instance_png", "encode_jpeg", "encode_laz", "encode_radar", "encode_semantic_png", "expert_file_name",
    "expert_frame_index", "instance_bgra", "instance_rgba", "read_anno", "read_depth_npz", "read_depth_png",
    "read_expert", "read_format_info", "read_instance_png", "read_jpeg", "read_laz", "read_quantization_tables", "read_radar",
    "read_semantic_png", "split_expert", "split_instance", "validate_anno", "write_anno", "write_depth_npz",
    "write_depth_png", "write_expert", "write_format_info", "write_instance_png", "write_jpeg", "write_laz",
    "write_radar", "write_semantic_png", "layout",
]  # fmt: skip
