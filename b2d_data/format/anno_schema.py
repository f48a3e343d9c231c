"""Key orders of the annotation JSON (format.md §3): the writer checks them, the loader relies on none."""

from __future__ import annotations

TOP_LEVEL_KEYS: tuple[str, ...] = (
    "x", "y", "throttle", "steer", "brake", "reverse", "theta", "speed",
    "x_command_far", "y_command_far", "command_far", "x_command_near", "y_command_near", "command_near",
    "should_brake", "x_target", "y_target", "next_command", "weather", "acceleration", "angular_velocity",
    "bounding_boxes", "sensors", "only_ap_brake",
)  # fmt: skip

CAMERA_SENSOR_KEYS: tuple[str, ...] = (
    "location", "rotation", "intrinsic", "world2cam", "cam2ego", "fov", "image_size_x", "image_size_y",
)  # fmt: skip
RADAR_SENSOR_KEYS: tuple[str, ...] = ("location", "rotation", "world2radar", "radar2ego")
LIDAR_SENSOR_KEYS: tuple[str, ...] = ("location", "rotation", "world2lidar", "lidar2ego")

EGO_KEYS: tuple[str, ...] = (
    "class", "id", "type_id", "base_type", "location", "rotation", "bbx_loc", "center", "extent", "world_cord",
    "semantic_tags", "color", "speed", "brake", "road_id", "lane_id", "section_id", "world2ego",
)  # fmt: skip
DYNAMIC_VEHICLE_KEYS: tuple[str, ...] = (
    "class", "state", "id", "location", "rotation", "bbx_loc", "center", "extent", "world_cord", "semantic_tags",
    "type_id", "color", "base_type", "num_points", "distance", "speed", "brake", "light_state", "road_id",
    "lane_id", "section_id", "world2vehicle",
)  # fmt: skip
STATIC_VEHICLE_KEYS: tuple[str, ...] = (
    "class", "state", "id", "location", "rotation", "bbx_loc", "center", "extent", "world_cord", "semantic_tags",
    "type_id", "num_points", "distance", "speed", "brake", "light_state", "road_id", "lane_id", "section_id",
    "world2vehicle",
)  # fmt: skip
WALKER_KEYS: tuple[str, ...] = (
    "class", "id", "location", "rotation", "bbx_loc", "center", "extent", "world_cord", "semantic_tags", "type_id",
    "gender", "age", "num_points", "distance", "speed", "bone", "road_id", "lane_id", "section_id", "world2ped",
)  # fmt: skip
TRAFFIC_LIGHT_KEYS: tuple[str, ...] = (
    "class", "id", "location", "rotation", "center", "extent", "semantic_tags", "type_id", "distance", "state",
    "affects_ego", "trigger_volume_location", "trigger_volume_rotation", "trigger_volume_extent", "road_id",
    "lane_id", "section_id",
)  # fmt: skip
TRIGGER_SIGN_KEYS: tuple[str, ...] = (
    "class", "id", "location", "rotation", "center", "extent", "semantic_tags", "type_id", "distance",
    "affects_ego", "trigger_volume_location", "trigger_volume_rotation", "trigger_volume_extent", "road_id",
    "lane_id", "section_id", "world2sign",
)  # fmt: skip
PROP_SIGN_KEYS: tuple[str, ...] = (
    "class", "id", "location", "rotation", "bbx_loc", "center", "extent", "world_cord", "semantic_tags", "type_id",
    "distance", "affects_ego", "road_id", "lane_id", "section_id", "world2sign",
)  # fmt: skip

#: ``state`` of a traffic light as json serialises carla.TrafficLightState.
TRAFFIC_LIGHT_STATES: dict[str, int] = {"Red": 0, "Yellow": 1, "Green": 2, "Off": 3, "Unknown": 4}


def box_keys(box: dict) -> tuple[str, ...]:
    """The key order a bounding-box entry of this class/state must follow."""
    cls = box.get("class")
    if cls == "ego_vehicle":
        return EGO_KEYS
    if cls == "vehicle":
        return STATIC_VEHICLE_KEYS if box.get("state") == "static" else DYNAMIC_VEHICLE_KEYS
    if cls == "walker":
        return WALKER_KEYS
    if cls == "traffic_light":
        return TRAFFIC_LIGHT_KEYS
    if cls == "traffic_sign":
        return TRIGGER_SIGN_KEYS if "trigger_volume_location" in box else PROP_SIGN_KEYS
    raise ValueError(f"unknown bounding-box class {cls!r}")


def check_anno(anno: dict) -> list[str]:
    """List every key-order or missing-key problem of an annotation dict (empty list: conforms)."""
    problems: list[str] = []
    if tuple(anno) != TOP_LEVEL_KEYS:
        problems.append(f"top-level keys {list(anno)} differ from {list(TOP_LEVEL_KEYS)}")
    for i, box in enumerate(anno.get("bounding_boxes", [])):
        try:
            expected = box_keys(box)
        except ValueError as exc:
            problems.append(f"bounding_boxes[{i}]: {exc}")
            continue
        if tuple(box) != expected:
            problems.append(f"bounding_boxes[{i}] ({box.get('class')}): keys {list(box)} differ from {list(expected)}")
    for sensor_id, entry in anno.get("sensors", {}).items():
        if sensor_id.startswith("CAM") or sensor_id == "TOP_DOWN":
            expected = CAMERA_SENSOR_KEYS
        elif sensor_id.startswith("RADAR"):
            expected = RADAR_SENSOR_KEYS
        else:
            expected = LIDAR_SENSOR_KEYS
        if tuple(entry) != expected:
            problems.append(f"sensors[{sensor_id}]: keys {list(entry)} differ from {list(expected)}")
    return problems
