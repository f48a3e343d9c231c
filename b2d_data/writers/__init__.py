"""Clip writer (atomic, optional process pool), clip archives and split lists."""

from b2d_data.writers.archive import (
    ArchiveInfo,
    archive_info,
    extract_archive,
    pack_clip,
    read_split_list,
    sha256_file,
    split_list_text,
    verify_archive,
    write_split_list,
)
from b2d_data.writers.clip_writer import ClipWriter, ClipWriterError, remove_stale_temporaries
from b2d_data.writers.frame_jobs import DepthOptions

__all__ = [
    "ArchiveInfo", "ClipWriter", "ClipWriterError", "DepthOptions", "archive_info", "extract_archive", "pack_clip",
    "read_split_list", "remove_stale_temporaries", "sha256_file", "split_list_text", "verify_archive",
    "write_split_list",
]  # fmt: skip
