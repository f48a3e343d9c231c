"""Visual checks: PNG montages of the rig (cameras, top-down, LiDAR BEV with boxes) for a town or a clip frame."""

from b2d_data.viz.montage import (
    boxes_from_anno,
    calibrations_from_anno,
    lidar_bev,
    make_montage,
    project_boxes,
    render_town_montage,
)

__all__ = [
    "boxes_from_anno", "calibrations_from_anno", "lidar_bev", "make_montage", "project_boxes", "render_town_montage",
]  # fmt: skip
