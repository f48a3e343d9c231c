"""Format versions recorded in every clip written by b2d-data."""

from __future__ import annotations

from enum import Enum

#: Name of the small JSON file inside each clip that records how it was written.
FORMAT_FILE = "b2d_format.json"


class FormatVersion(str, Enum):
    """Which on-disk layout a clip follows."""

    #: Byte-layout compatible with the released Bench2Drive Base/Full clips (uint8-metre depth PNG quirk).
    V0 = "bench2drive-v0"
    #: V0 plus float depth ``camera/depth_<cam>/NNNNN.npz`` (as Bench2Drive v0.0.4) and v0.0.4 radar mounts.
    V004 = "bench2drive-v0.0.4"

    @property
    def float_depth(self) -> bool:
        """Whether float depth npz files are written next to the depth PNGs."""
        return self is FormatVersion.V004


DEFAULT_FORMAT = FormatVersion.V0
