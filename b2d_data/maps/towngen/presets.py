"""Named town presets, and the entry points that turn (preset, seed) into OpenDRIVE text or a file."""

from __future__ import annotations

import logging
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from b2d_data.format.names import CARLA_TOWNS, is_town_name
from b2d_data.maps.towngen.cross_sections import TownWidths, boulevard, one_way, street
from b2d_data.maps.towngen.layouts import (
    GridSpec,
    add_grid,
    add_highway_loop,
    add_interurban_ring,
    add_interurban_u,
    grid_name,
)
from b2d_data.maps.towngen.model import Town
from b2d_data.maps.towngen.network import NetworkBuilder, NodeSpec, TownPlan
from b2d_data.maps.towngen.xodr_writer import to_xml

logger = logging.getLogger(__name__)

# Layout names (expert-and-scenarios.md §2.2): what a preset promises to contain.
TWO_WAY = "two_way_street"  # one lane each way, sidewalks, >= 250 m straight-ish
PARKING = "parking_lane"  # parking lane right of a driving lane
SHOULDER_CURVE = "shoulder_curve"  # two-way road with a shoulder, a curve after a straight (InvadingTurn)
MULTI_LANE = "multi_lane"  # >= 2 same-direction lanes, >= 200 m without a junction
BIKE_LANE = "bike_lane"  # biking lane continuing straight through a signalised junction
SIDEWALK = "sidewalk"
CROSSWALK = "crosswalk"
SIGNALIZED_4WAY = "signalized_4way"
SIGNALIZED_T = "signalized_t"
STOP_4WAY = "stop_4way"  # unsignalised 4-way with stop signs on some approaches
STOP_T = "stop_t"  # unsignalised T with a stop sign on the stem
UNCONTROLLED = "uncontrolled_junction"  # unsignalised, no signs
HIGHWAY_RAMPS = "highway_ramps"  # >= 2 lanes per direction, an on-ramp (merge) and an off-ramp (diverge)
INTERURBAN = "interurban"  # rural two-way road with T junctions
ONE_WAY = "one_way_street"  # one-way road with a parking lane and a sidewalk left of its leftmost lane

#: The layouts of the "all" preset (every one but ONE_WAY: its town stays as it was before one-way streets existed).
_ALL_PRESET_LAYOUTS: tuple[str, ...] = (
    TWO_WAY, PARKING, SHOULDER_CURVE, MULTI_LANE, BIKE_LANE, SIDEWALK, CROSSWALK, SIGNALIZED_4WAY, SIGNALIZED_T,
    STOP_4WAY, STOP_T, UNCONTROLLED, HIGHWAY_RAMPS, INTERURBAN,
)  # fmt: skip
ALL_LAYOUTS: tuple[str, ...] = (*_ALL_PRESET_LAYOUTS, ONE_WAY)

#: The preset a caller gets when it does not care: one town holding every layout but the one-way street.
DEFAULT_PRESET = "all"


class UnknownPresetError(ValueError):
    """A preset name that is not in ``TOWN_PRESETS``."""


@dataclass(frozen=True)
class TownPreset:
    """A named town recipe: its town name (``Town<digits>``), what it contains, and its planner."""

    name: str
    town: str
    description: str
    layouts: tuple[str, ...]
    planner: Callable[[TownPlan, np.random.Generator, TownWidths], None]
    #: ``b2d-collect --preset`` spreads any type's clips over this town (False: only the clips that need a place
    #: the other towns lack, e.g. the left kerb of a one-way street; their plans stay as they were).
    substitute: bool = True


def _spacings(rng: np.random.Generator, n: int, lo: float, hi: float) -> list[float]:
    return [round(float(rng.uniform(lo, hi)), 1) for _ in range(n)]


def _positions(spacings: list[float], sign: float) -> tuple[float, ...]:
    out = [0.0]
    for s in spacings:
        out.append(out[-1] + sign * s)
    return tuple(out)


def _corner_radii(rng: np.random.Generator, corners: list[tuple[int, int]]) -> dict[tuple[int, int], float]:
    return {p: round(float(rng.uniform(25.0, 45.0)), 1) for p in corners}


def _column_bump(rng: np.random.Generator) -> float:
    return float(np.radians(rng.uniform(1.5, 3.0))) * float(rng.choice([-1.0, 1.0]))


def _plan_urban(plan: TownPlan, rng: np.random.Generator, w: TownWidths) -> None:
    """4 x 3 grid: parking street on top, boulevard in the middle, plain street below; shoulder streets round the
    bottom corners; two 4-way and six T junctions with mixed control."""
    xs = _positions(_spacings(rng, 3, 250.0, 280.0), 1.0)
    ys = _positions(_spacings(rng, 2, 180.0, 210.0), -1.0)
    parking, blvd, plain = street(w, parking=True), boulevard(w), street(w)
    shoulder = street(w, shoulder=True)
    four = ["signal", "stop_minor"]
    rng.shuffle(four)
    tees = ["signal", "stop_minor", "stop_minor", "none"]
    rng.shuffle(tees)
    controls = {(1, 1): four[0], (2, 1): four[1], (0, 1): "signal", (3, 1): "signal"}
    controls.update(zip([(1, 0), (2, 0), (1, 2), (2, 2)], tees, strict=True))
    add_grid(
        plan,
        GridSpec(
            xs=xs, ys=ys,
            row_sections=(parking, blvd, plain),
            col_sections=(plain,) * 4,
            corner_sections={(0, 0): parking, (3, 0): parking, (0, 2): shoulder, (3, 2): shoulder},
            corner_radius=_corner_radii(rng, [(0, 0), (3, 0), (0, 2), (3, 2)]),
            controls=controls,
            column_bump=_column_bump(rng),
        ),
    )  # fmt: skip


def _two_row_grid(plan: TownPlan, rng: np.random.Generator, w: TownWidths) -> GridSpec:
    """4 x 2 grid: parking street on top, boulevard below; the boulevard's ends become junctions for the highway."""
    xs = _positions(_spacings(rng, 3, 250.0, 280.0), 1.0)
    ys = _positions(_spacings(rng, 1, 180.0, 210.0), -1.0)
    parking, blvd, plain = street(w, parking=True), boulevard(w), street(w)
    lower = ["signal", "stop_minor"]
    rng.shuffle(lower)
    controls = {
        (0, 1): "signal", (3, 1): "signal", (1, 1): lower[0], (2, 1): lower[1],
        (1, 0): str(rng.choice(["signal", "stop_all"])), (2, 0): str(rng.choice(["none", "stop_minor"])),
    }  # fmt: skip
    spec = GridSpec(
        xs=xs, ys=ys,
        row_sections=(parking, blvd),
        col_sections=(plain,) * 4,
        corner_sections={(0, 0): parking, (3, 0): parking},
        corner_radius=_corner_radii(rng, [(0, 0), (3, 0)]),
        controls=controls,
        extra_junctions=frozenset({(0, 1), (3, 1)}),
        column_bump=_column_bump(rng),
    )  # fmt: skip
    add_grid(plan, spec)
    return spec


def _node(plan: TownPlan, c: int, r: int) -> NodeSpec:
    node = plan.node(grid_name(c, r))
    if not isinstance(node, NodeSpec):
        raise TypeError(f"{grid_name(c, r)} is not a junction node")
    return node


def _plan_highway(plan: TownPlan, rng: np.random.Generator, w: TownWidths) -> None:
    """Two-row street grid with a highway loop over it: off-ramp into the top street, on-ramp back out."""
    _two_row_grid(plan, rng, w)
    lanes = int(rng.choice([2, 3]))
    add_highway_loop(plan, w, rng, _node(plan, 0, 1), _node(plan, 3, 1), _node(plan, 1, 0), _node(plan, 2, 0), lanes)


def _plan_interurban(plan: TownPlan, rng: np.random.Generator, w: TownWidths) -> None:
    """An interurban ring with a side road across it."""
    add_interurban_ring(plan, w, rng)


def _plan_all(plan: TownPlan, rng: np.random.Generator, w: TownWidths) -> None:
    """Two-row street grid, the highway loop with ramps above it and the interurban road hung below it."""
    _two_row_grid(plan, rng, w)
    add_highway_loop(plan, w, rng, _node(plan, 0, 1), _node(plan, 3, 1), _node(plan, 1, 0), _node(plan, 2, 0), 2)
    add_interurban_u(plan, w, rng, _node(plan, 1, 1), _node(plan, 2, 1))


def _plan_downtown(plan: TownPlan, rng: np.random.Generator, w: TownWidths) -> None:
    """4 x 3 grid whose two inner columns are one-way streets in opposite directions (two lanes, parking and a
    sidewalk on both kerbs); two-way parking streets on top, bottom and round the corners and a plain street across
    the middle, so that every junction stays reachable from every other."""
    xs = _positions(_spacings(rng, 3, 250.0, 280.0), 1.0)
    # longer blocks than the urban grid's: the left-kerb scenarios want up to ~150 m junction-free on a column
    ys = _positions(_spacings(rng, 2, 240.0, 270.0), -1.0)
    parking, plain, oneway = street(w, parking=True), street(w), one_way(w)
    four = ["signal", "stop_minor"]
    rng.shuffle(four)
    tees = ["signal", "signal", "stop_minor", "stop_minor", "none", "none"]
    rng.shuffle(tees)
    controls = {(1, 1): four[0], (2, 1): four[1]}
    controls.update(zip([(1, 0), (2, 0), (0, 1), (3, 1), (1, 2), (2, 2)], tees, strict=True))
    flow = [1, -1]
    rng.shuffle(flow)
    add_grid(
        plan,
        GridSpec(
            xs=xs, ys=ys,
            row_sections=(parking, plain, parking),
            col_sections=(parking, oneway, oneway, parking),
            corner_sections={(0, 0): parking, (3, 0): parking, (0, 2): parking, (3, 2): parking},
            corner_radius=_corner_radii(rng, [(0, 0), (3, 0), (0, 2), (3, 2)]),
            controls=controls,
            column_flow={1: flow[0], 2: flow[1]},
        ),
    )  # fmt: skip


TOWN_PRESETS: dict[str, TownPreset] = {
    p.name: p
    for p in (
        TownPreset(
            "all", "Town100",
            "every layout in one town: street grid with parking, boulevard with bike lanes, highway loop with ramps, "
            "interurban road",
            _ALL_PRESET_LAYOUTS, _plan_all,
        ),
        TownPreset(
            "urban", "Town101",
            "4 x 3 street grid: parking street, boulevard with bike lanes, shoulder corners, signalised and "
            "unsignalised 4-way and T junctions, sidewalks and crosswalks",
            (TWO_WAY, PARKING, SHOULDER_CURVE, MULTI_LANE, BIKE_LANE, SIDEWALK, CROSSWALK, SIGNALIZED_4WAY,
             SIGNALIZED_T, STOP_4WAY, STOP_T, UNCONTROLLED),
            _plan_urban,
        ),
        TownPreset(
            "highway", "Town102",
            "highway loop (2 or 3 lanes each way) with an off-ramp and an on-ramp joined to a small street grid",
            (TWO_WAY, PARKING, MULTI_LANE, BIKE_LANE, SIDEWALK, CROSSWALK, SIGNALIZED_T, STOP_T, UNCONTROLLED,
             HIGHWAY_RAMPS),
            _plan_highway,
        ),
        TownPreset(
            "interurban", "Town103",
            "interurban ring road with a side road: a T junction with a stop sign and an uncontrolled one",
            (SHOULDER_CURVE, STOP_T, UNCONTROLLED, INTERURBAN),
            _plan_interurban,
        ),
        TownPreset(
            "downtown", "Town104",
            "4 x 3 street grid with a pair of one-way streets in opposite directions (two lanes, parking lanes and "
            "sidewalks on both kerbs) between two-way parking streets; signalised and unsignalised 4-way and T "
            "junctions (the 4-ways have one-way arms)",
            (TWO_WAY, PARKING, SIDEWALK, CROSSWALK, SIGNALIZED_T, STOP_4WAY, STOP_T, UNCONTROLLED, MULTI_LANE,
             ONE_WAY),
            _plan_downtown, substitute=False,
        ),
    )
}  # fmt: skip

for _p in TOWN_PRESETS.values():
    # Clip names need Town<digits>; a CARLA name would collide with the real towns' data.
    if not is_town_name(_p.town) or _p.town in CARLA_TOWNS:
        raise RuntimeError(f"preset {_p.name!r} has an invalid town name {_p.town!r}")


def get_preset(preset: str) -> TownPreset:
    """The preset of that name; ``UnknownPresetError`` lists the known ones."""
    try:
        return TOWN_PRESETS[preset]
    except KeyError:
        known = ", ".join(sorted(TOWN_PRESETS))
        raise UnknownPresetError(f"unknown town preset {preset!r}; known presets: {known}") from None


def plan_town(preset: str, seed: int = 0) -> TownPlan:
    """The network plan of a preset for a seed (nodes, ramps and edges, before any geometry is laid)."""
    spec = get_preset(preset)
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng([int(seed), zlib.crc32(spec.name.encode("utf-8"))])
    widths = TownWidths.draw(rng)
    plan = TownPlan(spec.town, spec.name, int(seed))
    spec.planner(plan, rng, widths)
    return plan


def build_town(preset: str, seed: int = 0) -> Town:
    """The town's OpenDRIVE records for a preset and seed."""
    return NetworkBuilder(plan_town(preset, seed)).build()


def generate_town(preset: str, seed: int = 0) -> str:
    """OpenDRIVE 1.4 text of a preset's town; identical for identical (preset, seed)."""
    town = build_town(preset, seed)
    logger.debug(
        "generated %s (%s, seed %d): %d roads, %d junctions",
        town.name,
        preset,
        seed,
        len(town.roads),
        len(town.junctions),
    )
    return to_xml(town)


def write_town(preset: str, seed: int, path: str | Path) -> Path:
    """Write a preset's town; a directory gets ``<Town>.xodr`` (the stem is the map name the loader reports)."""
    spec = get_preset(preset)
    target = Path(path)
    if target.is_dir():
        target = target / f"{spec.town}.xodr"
    elif target.stem != spec.town:
        logger.warning(
            "%s: the loader names a map after its file stem; %s would keep clip names consistent", target, spec.town
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(generate_town(preset, seed), encoding="utf-8")
    return target
