"""The composition of ``b2d-collect --preset``: what each preset holds, the scaling rule, the town substitution.

Counts are worked out from the shipped JSON lists by regular expressions here, not by the parser the presets use.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from fractions import Fraction
from pathlib import Path

import pytest

from b2d_data.collection.preset_plan import PresetPlan
from b2d_data.collection.presets import (
    Composition,
    Slot,
    apportion,
    assign_towns,
    compose,
    half_up,
    interleaved,
    move_sides,
    scale,
    slots_of_names,
    spread,
)
from b2d_data.format.weather import WEATHER_IDS
from b2d_data.splits import corpus_manifest

# <Prefix>_Town.. ; the released base list holds one name cut off inside "Weather"
NAME = re.compile(r"^(?P<prefix>[A-Za-z0-9]+?)_(?P<town>Town\d+(?:HD)?)_Route\d+_Weathe?r?(?P<w>\d*)\.tar\.gz$")
# The two types whose XML name differs from the clip prefix (format.md §9)
XML_OF = {"LaneChange": "SequentialLaneChange", "TJunction": "T_Junction"}


def _prefix_counts(path: Path) -> Counter[str]:
    names = json.loads(path.read_text())
    return Counter(XML_OF.get(m["prefix"], m["prefix"]) for m in map(NAME.match, names))


def test_base_copies_the_official_list_type_by_type_with_the_zoo_val_split(b2d_data_dir):
    comp = compose("base")
    expected = _prefix_counts(b2d_data_dir / "bench2drive_base_1000.json")
    assert sum(expected.values()) == 1000 and len(expected) == 43  # format.md §1.2: 43 prefixes in base
    assert Counter(s.scenario for s in comp.slots) == expected
    zoo = json.loads((b2d_data_dir / "bench2drive_base_train_val_split.json").read_text())["val"]
    # the Zoo list names "v1/<clip>": the val slots copy exactly those 50 clips, the other 950 are train
    assert sorted(s.source for s in comp.slots if s.part == "val") == sorted(n[3:] for n in zoo)
    assert Counter(s.part for s in comp.slots) == {"train": 950, "val": 50}
    by_source = {s.source: s for s in comp.slots}
    slot = by_source["ParkingCrossingPedestrian_Town13_Route545_Weather25"]  # the Zoo list's first val clip
    assert (slot.scenario, slot.town, slot.weather, slot.part) == ("ParkingCrossingPedestrian", "Town13", 25, "val")
    # the truncated released name keeps its type and town, its weather is unknown
    cut = by_source["VehicleTurningRoutePedestrian_Town15_Route523_Weathe"]
    assert (cut.scenario, cut.town, cut.weather) == ("VehicleTurningRoutePedestrian", "Town15", None)
    assert [s.index for s in comp.slots] == list(range(1000))


def test_mini_copies_its_ten_clips_all_train(b2d_data_dir):
    comp = compose("mini")
    names = json.loads((b2d_data_dir / "bench2drive_mini_10.json").read_text())
    # (type, town, weather) read from the names by the regular expression
    expected = sorted((XML_OF.get(m["prefix"], m["prefix"]), m["town"], int(m["w"])) for m in map(NAME.match, names))
    assert sorted((s.scenario, s.town, s.weather) for s in comp.slots) == expected
    assert {s.part for s in comp.slots} == {"train"}  # the official mini has no val part


def test_full_takes_five_percent_val_with_every_type(b2d_data_dir):
    comp = compose("full")
    expected = _prefix_counts(b2d_data_dir / "bench2drive_full+sup_13638.json")
    assert Counter(s.scenario for s in comp.slots) == expected and len(expected) == 45  # 44 + NoScenario
    val = [s for s in comp.slots if s.part == "val"]
    assert len(val) == 682  # round(0.05 × 13638) = round(681.9); more than the 45 types
    assert {s.scenario for s in val} == set(expected)  # at least one of every type


def test_uniform_is_44_types_by_25_routes():
    comp = compose("uniform")
    per_type = Counter(s.scenario for s in comp.slots)
    assert len(per_type) == 44 and set(per_type.values()) == {25}
    # val: route 1 of each type
    val = [s for s in comp.slots if s.part == "val"]
    assert all(s.source.endswith("#1") for s in val) and len({s.scenario for s in val}) == 44
    assert Counter(s.part for s in comp.slots) == {"train": 1056, "val": 44}
    # weathers cycle over the 23 presets: 1100 = 23 × 47 + 19 -> 19 presets 48 times, 4 presets 47 times
    assert sorted(Counter(s.weather for s in comp.slots).values()) == [47] * 4 + [48] * 19
    # the val weathers (25 t mod 23 = 2 t mod 23 for t < 44) cover all 23 presets
    assert {s.weather for s in comp.slots if s.part == "val"} == set(WEATHER_IDS)


def test_scaling_rule_worked_by_hand():
    assert [half_up(Fraction(5, 2)), half_up(Fraction(7, 2)), half_up(Fraction(49, 20))] == [3, 4, 2]
    # counts 5, 3, 2 (N = 10) with 5 seats: quotas 2.5, 1.5, 1.0 -> floors 2, 1, 1; the one seat left goes to the
    # larger remainder, A and B tie at .5 and A sorts first
    assert apportion({"B": 3, "A": 5, "C": 2}, 5) == {"A": 3, "B": 1, "C": 1}
    # one seat: quotas .5, .3, .2 -> A
    assert apportion({"A": 5, "B": 3, "C": 2}, 1) == {"A": 1, "B": 0, "C": 0}
    # 3 of 5: floor((2j+1) 5 / 6) = 0, 2, 4; 7 of 3: floor((2j+1) 3 / 14) = 0,0,1,1,1,2,2
    assert spread(5, 3) == [0, 2, 4]
    assert spread(3, 7) == [0, 0, 1, 1, 1, 2, 2]
    assert spread(4, 4) == [0, 1, 2, 3]


def _slots(spec: list[tuple[str, str]]) -> Composition:
    return Composition("t", [Slot(i, t, 1, "Town12", part, f"{t}#{i}") for i, (t, part) in enumerate(spec)])


def test_scale_keeps_each_part_in_proportion():
    # train: A ×5, B ×3, C ×2; val: A ×1, B ×1
    comp = _slots([("A", "train")] * 5 + [("B", "train")] * 3 + [("C", "train")] * 2 + [("A", "val"), ("B", "val")])
    half = scale(comp, 0.5)
    # train: 5 seats -> A 3, B 1, C 1 (worked above); val: max(1, half_up(2 × .5)) = 1 seat, tie A/B -> A
    assert Counter((s.scenario, s.part) for s in half.slots) == {
        ("A", "train"): 3,
        ("B", "train"): 1,
        ("C", "train"): 1,
        ("A", "val"): 1,
    }
    # A keeps positions 0, 2, 4 of its 5 train slots (indexes 0..4), B position floor(3/2) = 1 (index 6),
    # C position floor(2/2) = 1 (index 9); A's val slot is index 10
    assert [s.source for s in half.slots] == ["A#0", "A#2", "A#4", "B#6", "C#9", "A#10"]
    assert [s.index for s in half.slots] == list(range(6))
    # a tiny factor keeps one clip per part: max(1, half_up(10 × .01)) = 1 train (A, the largest), 1 val
    assert [(s.source, s.part) for s in scale(comp, 0.01).slots] == [("A#2", "train"), ("A#10", "val")]
    # doubling repeats every slot: 20 train + 4 val
    assert Counter(s.source for s in scale(comp, 2).slots) == {s.source: 2 for s in comp.slots}


def test_base_scaled_by_a_tenth():
    full, tenth = compose("base"), compose("base", 0.1)
    assert Counter(s.part for s in tenth.slots) == {"train": 95, "val": 5}  # 950 / 10, 50 / 10
    train = Counter(s.scenario for s in full.slots if s.part == "train")
    kept = Counter(s.scenario for s in tenth.slots if s.part == "train")
    # the largest-remainder rule gives each type its quota n/10 rounded down or up
    assert all(kept[t] in (n // 10, -(-n // 10)) for t, n in train.items())
    # every kept slot copies a clip of base, its part unchanged
    parts = {s.source: s.part for s in full.slots}
    assert all(parts[s.source] == s.part for s in tenth.slots)


def test_unknown_types_and_bad_names_are_reported_not_fatal():
    comp = slots_of_names(
        ["Accident_Town03_Route1_Weather2.tar.gz", "Teleport_Town01_Route7_Weather3.tar.gz",
         "Teleport_Town02_Route8_Weather3.tar.gz", "readme.txt"]
    )  # fmt: skip
    assert [(s.scenario, s.town, s.weather) for s in comp.slots] == [("Accident", "Town03", 2)]
    assert comp.unknown == {"Teleport": 2} and comp.malformed == ["readme.txt"]
    plan = PresetPlan(comp, {0: "Town100"})
    assert plan.left_out() == {"unknown scenario type Teleport": 2, "not a clip name": 1}


def test_unknown_type_in_a_list_file_gives_a_composition(tmp_path):
    lists = tmp_path / "lists"
    lists.mkdir()
    (lists / "bench2drive_mini_10.json").write_text(
        json.dumps({"Teleport_Town01_Route7_Weather3.tar.gz": {}, "HardBreakRoute_Town01_Route30_Weather3.tar.gz": {}})
    )
    comp = compose("mini", lists_dir=lists)
    assert [s.source for s in comp.slots] == ["HardBreakRoute_Town01_Route30_Weather3"]
    assert comp.unknown == {"Teleport": 1}


def test_town_substitution_by_hand():
    slots = [
        Slot(0, "Accident", 1, "Town01", "train", "a"),  # Town01 is shipped but holds no Accident
        Slot(1, "Accident", 1, "Town12", "train", "b"),  # Town12 is not shipped
        Slot(2, "HardBreakRoute", 1, "Town01", "train", "c"),  # kept
        Slot(3, "Accident", 1, "Town04", "train", "d"),  # kept
        Slot(4, "HardBreakRoute", 1, "Town13", "train", "e"),
        Slot(5, "Accident", 1, "Town12", "val", "f"),
        Slot(6, "Nowhere", 1, "Town12", "train", "g"),
    ]
    hosts = {("Town04", "Accident"), ("Town01", "HardBreakRoute"), ("Town100", "Accident"), ("Town102", "Accident"),
             ("Town100", "HardBreakRoute"), ("Town101", "HardBreakRoute"), ("Town103", "HardBreakRoute")}  # fmt: skip
    generated = ["Town100", "Town101", "Town102", "Town103"]
    towns = assign_towns(slots, lambda town, kind: (town, kind) in hosts, ["Town01", "Town04"], generated)
    # Accident is the 1st type needing a substitute: its round starts at its 1st host (Town100) and goes on
    # Town102, Town100 (slots 0, 1, 5). HardBreakRoute is the 2nd: it starts at its 2nd host, Town101 (slot 4).
    assert towns == {0: "Town100", 1: "Town102", 2: "Town01", 3: "Town04", 4: "Town101", 5: "Town100", 6: None}


def test_side_moves_by_hand():
    slots = [
        Slot(0, "ParkingCutIn", 1, "", "train", "a"),  # left drawn, Town101 has no left kerb: moves to Town104
        Slot(1, "ParkingCutIn", 1, "", "train", "b"),  # right: stays, pinned right
        Slot(2, "ParkingCutIn", 1, "", "train", "c"),  # left: moves, the (type, side)'s 2nd turn: Town105
        Slot(3, "ParkingExit", 1, "", "train", "d"),  # left: no town has one for ParkingExit: stays, unpinned
        Slot(4, "HardBreakRoute", 1, "", "train", "e"),  # draws no side
        Slot(5, "ParkingCutIn", 1, "", "train", "f"),  # left, and already in a town holding it: pinned there
    ]
    towns = {0: "Town101", 1: "Town101", 2: "Town100", 3: "Town101", 4: "Town100", 5: "Town104"}
    sides = {0: "left", 1: "right", 2: "left", 3: "left", 5: "left"}
    left_kerbs = {("Town104", "ParkingCutIn"), ("Town105", "ParkingCutIn")}

    def has_side(town: str, kind: str, side: str) -> bool:
        return side == "right" or (town, kind) in left_kerbs

    moved, pinned = move_sides(slots, towns, sides, has_side, ["Town100", "Town101", "Town104", "Town105"])
    assert moved == {0: "Town104", 1: "Town101", 2: "Town105", 3: "Town101", 4: "Town100", 5: "Town104"}
    assert pinned == {0: "left", 1: "right", 2: "left", 5: "left"}


def test_a_left_drawn_slot_lands_in_the_one_way_town(tmp_path):
    """Four ParkingCutIn slots; seed 0 draws right, right, left, left for slots 0-3 (27 of 111 left): the right ones
    stay in Town101 (the only substitute town here), the left ones go to Town104 and keep to the left kerb."""
    from b2d_data.collection.job import CollectConfig
    from b2d_data.collection.preset_plan import _plan_routes, _Towns, drawn_sides

    slots = [Slot(i, "ParkingCutIn", None, "", "train", f"ParkingCutIn#{i}") for i in range(4)]
    assert drawn_sides(slots, "training", 0) == {0: "right", 1: "right", 2: "left", 3: "left"}
    towns = _Towns(tmp_path)
    assert "Town104" not in towns.generated and "Town104" in towns.sided
    towns.generated, towns.sided = ["Town101"], ["Town101", "Town104"]
    config = CollectConfig(out=tmp_path, preset="uniform", attempts_per_clip=1)
    assigned, routes, errors = _plan_routes(Composition("t", slots), towns, config)
    assert errors == {} and assigned == {0: "Town101", 1: "Town101", 2: "Town104", 3: "Town104"}
    for index, side in ((0, "right"), (1, "right"), (2, "left"), (3, "left")):
        (route,) = routes[index]
        assert route.town == assigned[index] and route.scenarios[0].parameter("direction") == side


def test_interleaved_order_mixes_types():
    slots = [Slot(i, t, 1, "", "train", str(i)) for i, t in enumerate("AAAABB")]
    # A at (k + 1/2) / 4 = 1/8, 3/8, 5/8, 7/8; B at 1/4, 3/4
    assert [s.index for s in interleaved(slots)] == [0, 4, 1, 2, 5, 3]


def test_corpus_manifest_is_the_one_json_in_splits(tmp_path):
    with pytest.raises(FileNotFoundError, match="no split manifest"):
        corpus_manifest(tmp_path)
    (tmp_path / "splits").mkdir()
    (tmp_path / "splits" / "base.json").write_text("{}")
    assert corpus_manifest(tmp_path) == tmp_path / "splits" / "base.json"
    (tmp_path / "splits" / "mini.json").write_text("{}")
    with pytest.raises(ValueError, match="base.json, mini.json"):
        corpus_manifest(tmp_path)


def test_summary_adds_a_types_slots_into_one_row_with_why_clips_are_missing(tmp_path):
    from types import SimpleNamespace

    from b2d_data.collection import run_log as rl
    from b2d_data.collection.plan import CollectionPlan, RouteTask, ScenarioPlan
    from b2d_data.collection.runner import summarise, summary_table

    def task(route_id: str, scenario: str, group: str) -> RouteTask:
        return RouteTask(SimpleNamespace(id=route_id), SimpleNamespace(name="Town100"), scenario, 0, group)

    plan = CollectionPlan(
        [
            ScenarioPlan("Accident", 1, [task("100", "Accident", "#0"), task("101", "Accident", "#0")], group="#0"),
            ScenarioPlan("Accident", 1, [], "no town holds a place for Accident", group="#1"),
            ScenarioPlan("HardBreakRoute", 1, [task("300", "HardBreakRoute", "#2")], group="#2"),
        ],
        towns=[],
        settings={},
    )
    attempt = rl.EVENT_ATTEMPT
    records = [
        {"event": attempt, "route_id": "100", "status": "failed", "reason": "collision"},
        {"event": attempt, "route_id": "101", "status": "clip", "clip": "Accident_Town100_Route101_Weather1"},
        {"event": attempt, "route_id": "300", "status": "failed", "reason": "TickRuntime"},
    ]
    rows = {s.scenario: s for s in summarise(plan, records, tmp_path, sensors=False)}
    # Accident: slots #0 and #1 -> 2 wanted; #0 made its clip at the 2nd attempt, #1 has no routes
    accident = rows["Accident"]
    assert (accident.clips, accident.requested, accident.attempts, accident.failed) == (1, 2, 2, 1)
    assert accident.reasons == {"collision": 1} and accident.note == "no town holds a place for Accident"
    assert (rows["HardBreakRoute"].clips, rows["HardBreakRoute"].reasons) == (0, {"TickRuntime": 1})
    table = summary_table(SimpleNamespace(scenarios=list(rows.values())))
    assert "Accident        1/2" in table and "HardBreakRoute  0/1" in table
    # the Accident row names both reasons: the failed attempt and the slot without a town
    assert "collision ×1; no town holds a place for Accident" in table
