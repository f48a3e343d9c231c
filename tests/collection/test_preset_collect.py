"""``b2d-collect --preset`` end to end: the real plan of mini (towns kept or substituted), a tiny scaled base
collected at a tiny resolution and loaded by split, its resume, and the option errors.

The collected routes are cut a few metres past their trigger point (as test_collect.py cuts its routes) so that a
clip takes seconds; what is tested is the preset's plumbing, not the scenarios.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from pathlib import Path

import pytest

from b2d_data.cli.collect import main
from b2d_data.collection import run_log as rl
from b2d_data.collection.job import CollectConfig
from b2d_data.collection.plan import CollectError, plan_collection
from b2d_data.format.names import ClipName
from b2d_data.scenarios import placement
from b2d_data.splits import SplitManifest

from .test_collect import TINY

GENERATED = {"Town100", "Town101", "Town102", "Town103"}
SHIPPED = {"Town01", "Town04", "Town06", "Town07", "Town10HD"}
NAME = re.compile(r"^(?P<prefix>[A-Za-z0-9]+?)_(?P<town>Town\d+(?:HD)?)_Route\d+_Weathe?r?(?P<w>\d*)")
PAST_TRIGGER = 10.0  # m of route kept after the trigger point


@pytest.fixture(scope="module")
def mini_plan(tmp_path_factory):
    out = tmp_path_factory.mktemp("mini")
    return out, plan_collection(CollectConfig(out=out, preset="mini"))


def test_mini_plan_keeps_shipped_towns_that_hold_the_type_and_substitutes_the_rest(mini_plan, carla_maps_dir):
    out, plan = mini_plan
    preset = plan.preset
    town_of = {s.source: preset.towns[s.index] for s in preset.composition.slots}
    # Town01 and Town04 ship and hold HardBreakRoute and YieldToEmergencyVehicle: kept
    assert town_of["HardBreakRoute_Town01_Route30_Weather3"] == "Town01"
    assert town_of["YieldToEmergencyVehicle_Town04_Route165_Weather7"] == "Town04"
    # Town10HD ships but placement builds no ParkedObstacle route there (premise checked here): substituted
    from b2d_data.maps import load_opendrive

    with pytest.raises(placement.PlacementError):
        placement.make_routes(load_opendrive(carla_maps_dir / "Town10HD.xodr"), "ParkedObstacle", 1)
    assert town_of["ParkedObstacle_Town10HD_Route371_Weather7"] in GENERATED
    # the other seven are on towns b2d-data does not ship (Town02, 03, 05, 11, 12, 13, 15): generated towns
    others = {k: v for k, v in town_of.items() if NAME.match(k)["town"] not in SHIPPED}
    assert len(others) == 7 and set(others.values()) <= GENERATED
    # spread: the substitutes use more than one generated town
    assert len(set(others.values())) > 1
    # every slot: 3 attempts (the default) in its town, at its weather, ids (index + 1) * 100 + attempt
    by_group = {sp.group: sp for sp in plan.scenarios}
    for slot in preset.composition.slots:
        sp = by_group[f"#{slot.index}"]
        assert (sp.scenario, sp.target) == (slot.scenario, 1)
        assert [t.route.id for t in sp.tasks] == [str((slot.index + 1) * 100 + a) for a in range(3)]
        assert {t.route.town for t in sp.tasks} == {town_of[slot.source]}
        assert {t.route.weather_id for t in sp.tasks} == {slot.weather}
        assert {t.route.scenario_type for t in sp.tasks} == {slot.scenario}


def test_placement_side_by_side_gives_the_routes_of_one_process(tmp_path, monkeypatch):
    """``place_all`` on a process pool: the same towns, routes and errors as every call in this process, and no
    placement call left in this process (the probes of assign_towns included)."""
    from b2d_data.collection import preset_plan as pp

    calls = []
    routes = pp._Placer.routes
    monkeypatch.setattr(pp._Placer, "routes", lambda self, *a, **k: (calls.append(a), routes(self, *a, **k))[1])
    monkeypatch.setattr(pp, "PARALLEL_FROM", 10**9)
    one = plan_collection(CollectConfig(out=tmp_path / "one", preset="mini"))
    assert len(calls) > 10  # probes and groups, here
    calls.clear()
    monkeypatch.setattr(pp, "PARALLEL_FROM", 1)
    monkeypatch.setattr(pp, "usable_cores", lambda: 2)
    pooled = plan_collection(CollectConfig(out=tmp_path / "pooled", preset="mini"))
    assert calls == []
    assert pooled.preset.towns == one.preset.towns and pooled.preset.errors == one.preset.errors
    assert [(sp.group, [t.route for t in sp.tasks]) for sp in pooled.scenarios] == [
        (sp.group, [t.route for t in sp.tasks]) for sp in one.scenarios
    ]


def test_resumed_plan_is_read_back_without_placement(mini_plan, monkeypatch):
    out, plan = mini_plan

    def no_placement(*args, **kwargs):
        raise AssertionError("placement ran again on resume")

    monkeypatch.setattr(placement, "make_routes", no_placement)
    again = plan_collection(CollectConfig(out=out, preset="mini", resume=True))
    assert [(sp.group, [t.route for t in sp.tasks]) for sp in again.scenarios] == [
        (sp.group, [t.route for t in sp.tasks]) for sp in plan.scenarios
    ]
    assert again.preset.towns == plan.preset.towns


def _cut_after_trigger(town, route):
    """The route up to ``PAST_TRIGGER`` m beyond the keypoint nearest its trigger point."""
    from b2d_data.scenarios.route import DenseRoute
    from b2d_data.scenarios.triggers import trigger_route_index

    trigger = route.scenarios[0].trigger_point.location
    points = route.waypoints
    near = min(range(len(points)), key=lambda i: math.hypot(points[i].x - trigger.x, points[i].y - trigger.y))
    end = near
    while end + 1 < len(points) and math.hypot(points[end].x - points[near].x,
                                               points[end].y - points[near].y) < PAST_TRIGGER:  # fmt: skip
        end += 1
    cut = replace(route, waypoints=points[: end + 1])
    assert trigger_route_index(DenseRoute.from_route(town, cut), route.scenarios[0].trigger_point) is not None
    return cut


def _official(b2d_data_dir: Path) -> tuple[str, str]:
    """(train, val) clip that base scaled by 0.001 copies, worked out from the JSON lists by regular expressions:
    each part keeps max(1, round(N × 0.001)) = 1 clip (950 → 0.95, 50 → 0.05), of the type with the most clips in
    that part (ties: the name sorting first), the middle one (position n // 2) of that type's clips sorted by name."""
    names = sorted(n[: -len(".tar.gz")] for n in json.loads((b2d_data_dir / "bench2drive_base_1000.json").read_text()))
    zoo = {n[3:] for n in json.loads((b2d_data_dir / "bench2drive_base_train_val_split.json").read_text())["val"]}
    xml = {"LaneChange": "SequentialLaneChange", "TJunction": "T_Junction"}
    chosen = []
    for part in (lambda n: n not in zoo, lambda n: n in zoo):
        by_type: dict[str, list[str]] = {}
        for n in filter(part, names):
            prefix = NAME.match(n)["prefix"]
            by_type.setdefault(xml.get(prefix, prefix), []).append(n)
        kind = min(by_type, key=lambda t: (-len(by_type[t]), t))
        chosen.append(by_type[kind][len(by_type[kind]) // 2])
    return chosen[0], chosen[1]


@pytest.fixture(scope="module")
def scaled_base(tmp_path_factory):
    """base × 0.001 collected at a tiny resolution (routes cut after their trigger); (out, stdout of the run)."""
    real = placement.make_routes

    def short_routes(town, scenario_type, n, seed=0, weathers=None, params="training", **pinned):
        return [_cut_after_trigger(town, r) for r in real(town, scenario_type, n, seed, weathers, params, **pinned)]

    out = tmp_path_factory.mktemp("preset") / "base"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(placement, "make_routes", short_routes)
        args = ["--preset", "base", "--n-scale", "0.001", "--attempts-per-clip", "2", "--out", str(out), *TINY]
        assert main(args) == 0
    return out, args


def test_scaled_base_collects_its_slots_and_loads_by_split(scaled_base, b2d_data_dir, capsys):
    from b2d_data import ClipDataset

    out, _ = scaled_base
    train_src, val_src = _official(b2d_data_dir)
    manifest = SplitManifest.load(out / "splits" / "base.json")
    assert (len(manifest.train), len(manifest.val)) == (1, 1)
    (train_clip,), (val_clip,) = manifest.clips("train"), manifest.clips("val")
    assert manifest.extra["copies"] == {train_clip: train_src, val_clip: val_src}
    assert manifest.extra["missing"] == []
    for ours, theirs in ((train_clip, train_src), (val_clip, val_src)):
        name, official = ClipName.parse(ours), ClipName.parse(theirs)
        assert (name.scenario, name.weather_id) == (official.scenario, official.weather_id)
        # the official town where it ships, else a generated one
        assert name.town == official.town if official.town in SHIPPED else name.town in GENERATED
        assert (out / ours / "anno").is_dir()
    frames = {r["clip"]: r["frames"] for r in rl.final_records(rl.read_run_log(out / rl.LOG_FILE))
              if r["status"] == "clip"}  # fmt: skip
    for part, clip in (("train", train_clip), ("val", val_clip)):
        ds = ClipDataset(out, split=part)
        assert len(ds) == frames[clip]
        assert ds[0]["clip"] == clip and ds[len(ds) - 1]["clip"] == clip
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] and summary["manifest_clips"] == [1, 1]
    rows = {s["scenario"]: (s["clips"], s["requested"]) for s in summary["scenarios"]}
    assert rows == {ClipName.parse(train_src).xml_type: (1, 1), ClipName.parse(val_src).xml_type: (1, 1)}


def test_resume_of_a_complete_preset_runs_nothing_and_keeps_the_manifest(scaled_base, capsys):
    out, args = scaled_base
    before = (out / "splits" / "base.json").read_text()
    attempts = len(rl.final_records(rl.read_run_log(out / rl.LOG_FILE)))
    capsys.readouterr()
    assert main([*args, "--resume"]) == 0
    printed = capsys.readouterr().out
    assert "0 clips from 0 attempts" in printed and "1 train + 1 val clips" in printed
    assert len(rl.final_records(rl.read_run_log(out / rl.LOG_FILE))) == attempts
    assert (out / "splits" / "base.json").read_text() == before


@pytest.mark.parametrize(
    "argv, text",
    [
        (["--preset", "base", "--scenario", "Accident"], "drop --scenario"),
        (["--preset", "mini", "--n", "3", "--town", "urban"], "drop --n, --town"),
        (["--scenario", "Accident", "--n-scale", "0.5"], "--n-scale scales a --preset"),
        (["--preset", "base", "--n-scale", "0"], "--n-scale must be positive"),
    ],
)
def test_preset_option_errors(argv, text, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--out", str(tmp_path / "x"), *TINY])
    assert exc.value.code == 2 and text in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_unknown_preset_through_the_api_is_a_collect_error(tmp_path):
    with pytest.raises(CollectError, match="unknown preset 'huge'"):
        plan_collection(CollectConfig(out=tmp_path, preset="huge"))
