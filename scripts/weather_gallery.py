"""Render the rig at one place of a town under each of the 23 weathers and measure how the road reads.

    python scripts/weather_gallery.py                                   # Town100 and Town10HD, gallery of both
    python scripts/weather_gallery.py --town Town10HD --no-images       # figures only

For every town and weather it prints the mean luma (Rec. 601, 0–255) of the road 5–30 m ahead in the ego's lane in
the FRONT camera, relative to clear noon (weather 0) at the same place, and for weathers with sun shadows the
shadow contrast: (L_sun − L_shadow) / L_sun over the road pixels of the six cameras (within 60 m) that a shadow
falls on, from the same views rendered without and with shadows. Gallery: one JPEG per town and weather (six
cameras and the top-down camera) in ``docs/gallery/`` and an ``index.md`` with the table.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from pathlib import Path

import cv2
import numpy as np

from b2d_data.format.rig import CAMERA_BY_FOLDER, CAMERAS
from b2d_data.format.weather import PRESETS, WEATHER_IDS, WeatherParameters
from b2d_data.maps import LaneType
from b2d_data.maps.towns import resolve_town
from b2d_data.sim.api import RigConfig
from b2d_data.sim.builtin.sensors.lighting import Lighting
from b2d_data.sim.builtin.sensors.suite import SensorSuite
from b2d_data.viz.road_light import ROAD_TAGS, lane_ahead_mask, luma, shadow_contrast
from b2d_data.viz.town_scene import town_snapshot

#: Weather the luminance is relative to: clear noon.
REFERENCE = 0
GRID = (("front_left", "front", "front_right"), ("back_left", "back", "back_right"))


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return int(w), int(h)


def _label(weather_id: int, w: WeatherParameters) -> str:
    return (f"weather {weather_id}: sun {w.sun_altitude_angle:g} deg, cloud {w.cloudiness:g}, rain {w.precipitation:g},"
            f" fog {w.fog_density:g}")  # fmt: skip


def _montage(cameras: dict[str, np.ndarray], tile: tuple[int, int], text: str) -> np.ndarray:
    """Six cameras in two rows, the top-down camera below the middle, a caption on the left of the last row."""
    w, h = tile

    def fit(img: np.ndarray | None) -> np.ndarray:
        if img is None:
            return np.zeros((h, w, 3), np.uint8)
        return cv2.resize(np.ascontiguousarray(img[..., :3]), (w, h), interpolation=cv2.INTER_AREA)

    rows = [np.hstack([fit(cameras.get(name)) for name in names]) for names in GRID]
    caption = np.full((h, w, 3), 24, np.uint8)
    for k, line in enumerate(text.split(": ", 1)[0:1] + text.split(": ", 1)[1].split(", ")):
        cv2.putText(caption, line, (8, 22 + 20 * k), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (230, 230, 230), 1, cv2.LINE_AA)
    rows.append(np.hstack([caption, fit(cameras.get("top_down")), np.full((h, w, 3), 24, np.uint8)]))
    return np.vstack(rows)


@dataclasses.dataclass
class Row:
    """Figures of one town and weather."""

    town: str
    weather: int
    road_luma: float
    relative: float
    shadow: tuple[float, int] | None
    image: str | None


def measure_town(name: str, weathers: list[int], size: tuple[int, int], tile: tuple[int, int] | None,
                 out: Path, quality: int) -> list[Row]:  # fmt: skip
    """Render ``weathers`` at the town's default place; write the gallery JPEGs when ``tile`` is given."""
    town = resolve_town(name)
    snapshot, ego_id = town_snapshot(town, None, PRESETS[REFERENCE], seed=0)
    ego = snapshot.actors[ego_id]
    waypoint = town.get_waypoint(ego.location, project_to_road=True, lane_type=LaneType.DRIVING)
    half_width = 0.5 * float(waypoint.lane_width) if waypoint is not None else 1.75
    w, h = size
    config = RigConfig(width=w, height=h, top_down_width=w, top_down_height=h, lidar=False, radar=False)
    suite = SensorSuite(town, config, seed=0)
    front = CAMERA_BY_FOLDER["front"]
    rows: list[Row] = []
    try:
        assert suite.renderer is not None
        order = [REFERENCE] + [i for i in weathers if i != REFERENCE]
        reference = None
        for weather_id in order:
            weather = PRESETS[weather_id]
            data = suite.capture(dataclasses.replace(snapshot, weather=weather), ego_id)
            cams = data.cameras
            mask = lane_ahead_mask(cams["front"].depth, cams["front"].semantic, front.intrinsic(w, h),
                                   front.mount.matrix(), half_width=half_width)  # fmt: skip
            road = float(luma(cams["front"].rgb)[mask].mean()) if mask.any() else float("nan")
            reference = road if reference is None else reference
            shadow = None
            if Lighting.from_weather(weather).shadow_strength > 0.0:
                suite.renderer.shadows = False
                try:
                    flat = suite.capture(dataclasses.replace(snapshot, weather=weather), ego_id).cameras
                finally:
                    suite.renderer.shadows = True
                lit = np.concatenate([flat[c.folder].rgb for c in CAMERAS])
                shaded = np.concatenate([cams[c.folder].rgb for c in CAMERAS])
                near_road = np.concatenate(
                    [np.isin(cams[c.folder].semantic, ROAD_TAGS) & (cams[c.folder].depth < 60.0) for c in CAMERAS]
                )
                shadow = shadow_contrast(lit, shaded, near_road)
            image = None
            if tile is not None:
                image = f"{name}_w{weather_id:02d}.jpg"
                picture = _montage({k: f.rgb for k, f in cams.items()}, tile, _label(weather_id, weather))
                ok = cv2.imwrite(str(out / image), cv2.cvtColor(picture, cv2.COLOR_RGB2BGR),
                                 [cv2.IMWRITE_JPEG_QUALITY, quality])  # fmt: skip
                if not ok:
                    raise OSError(f"cannot write {out / image}")
            if weather_id in weathers:
                rows.append(Row(name, weather_id, road, road / reference, shadow, image))
                _print_row(rows[-1])
    finally:
        suite.close()
    return rows


def _print_row(row: Row) -> None:
    w = PRESETS[row.weather]
    shadow = f"{100 * row.shadow[0]:5.1f} % ({row.shadow[1]} px)" if row.shadow and row.shadow[1] else "-"
    print(f"{row.town:<10} {row.weather:>3}  sun {w.sun_altitude_angle:>4g}  fog {w.fog_density:>4g}  "
          f"cloud {w.cloudiness:>4g}  road luma {row.road_luma:6.1f}  relative {row.relative:5.2f}  "
          f"shadow contrast {shadow}", flush=True)  # fmt: skip


def _index(rows: list[Row], out: Path) -> None:
    lines = [
        "# Weather gallery",
        "",
        "Written by `python scripts/weather_gallery.py`: the six cameras and the top-down camera at one place of each",
        "town under each of the 23 Bench2Drive weathers. *Road* is the mean luma of the road 5–30 m ahead in the",
        "ego's lane (FRONT camera) relative to clear noon (weather 0) at the same place; *shadow* the darkening of the",
        "road where a sun shadow falls (six cameras, within 60 m).",
        "",
        "| town | weather | sun ° | cloud | rain | fog | road | shadow | image |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        w = PRESETS[r.weather]
        shadow = f"{100 * r.shadow[0]:.0f} %" if r.shadow and r.shadow[1] else "–"
        image = f"[{r.image}]({r.image})" if r.image else ""
        lines.append(f"| {r.town} | {r.weather} | {w.sun_altitude_angle:g} | {w.cloudiness:g} | {w.precipitation:g} "
                     f"| {w.fog_density:g} | {r.relative:.2f} | {shadow} | {image} |")  # fmt: skip
    (out / "index.md").write_text("\n".join(lines) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--town", action="append", help="town to render (repeatable; default Town100 and Town10HD)")
    parser.add_argument("--weather", type=int, action="append", help="weather id (repeatable; default all 23)")
    parser.add_argument("--size", default="480x270", help="rendered camera size WxH (default 480x270)")
    parser.add_argument("--tile", default="320x180", help="gallery tile size WxH (default 320x180)")
    parser.add_argument("--quality", type=int, default=72, help="JPEG quality of the gallery (default 72)")
    parser.add_argument("--out", type=Path, default=Path("docs/gallery"), help="gallery folder (default docs/gallery)")
    parser.add_argument("--no-images", action="store_true", help="print the figures only")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    weathers = args.weather or list(WEATHER_IDS)
    unknown = sorted(set(weathers) - set(WEATHER_IDS))
    if unknown:
        parser.error(f"unknown weather ids {unknown}; valid: {', '.join(map(str, WEATHER_IDS))}")
    tile = None if args.no_images else _size(args.tile)
    if tile is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    rows: list[Row] = []
    for town in args.town or ["Town100", "Town10HD"]:
        rows += measure_town(town, weathers, _size(args.size), tile, args.out, args.quality)
    if tile is not None:
        _index(rows, args.out)
        total = sum(p.stat().st_size for p in args.out.glob("*.jpg"))
        print(f"{args.out}: {len(list(args.out.glob('*.jpg')))} JPEGs, {total / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
