"""The two LB2.0 training types Bench2Drive drops are known types without breaking Bench2Drive's 44.

Bench2Drive's ``ability_benchmark.py`` maps only its own 44 types to abilities, so EnterActorFlowV2 and
PriorityAtJunction count in none; route files, clip names, ``b2d-collect --scenario`` and route ids take them.
"""

from __future__ import annotations

from b2d_data.collection.plan import implemented_scenarios, resolve_scenario
from b2d_data.eval.abilities import ABILITIES, compute_abilities
from b2d_data.format.leaderboard import STATUS_COMPLETED, RouteRecord
from b2d_data.format.names import ClipName, canonical_clip_prefix
from b2d_data.format.scenario_types import (
    BY_XML_TYPE,
    LB2_ONLY_TYPES,
    NO_SCENARIO,
    SCENARIO_TYPES,
    abilities_of,
    scenario_type,
)
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.scenarios.placement import route_id
from b2d_data.scenarios.route_xml import Route, ScenarioConfig, read_routes, write_routes

NEW = ("EnterActorFlowV2", "PriorityAtJunction")


def test_bench2drive_keeps_its_44_and_the_two_lb2_types_are_known_with_no_ability():
    assert len(SCENARIO_TYPES) == 44 and not set(NEW) & {t.xml_type for t in SCENARIO_TYPES}
    assert tuple(t.xml_type for t in LB2_ONLY_TYPES) == NEW
    for name in NEW:
        # Bench2Drive's clip-prefix style: the class name itself (only names with "_" or SequentialLaneChange differ)
        assert BY_XML_TYPE[name].clip_prefix == name == canonical_clip_prefix(name)
        assert abilities_of(name) == () and scenario_type(name).xml_type == name
        assert resolve_scenario(name) == name and name in implemented_scenarios()
        clip = ClipName.parse(f"{name}_Town100_Route41450001_Weather12")
        assert clip.xml_type == name and clip.is_known_scenario


def test_route_ids_of_the_new_types_follow_no_scenario_and_stay_unique():
    # (seed × 100 + index) × 10000 + k + 1: the 44 keep 0..43, NoScenario 44, then EnterActorFlowV2 45 and
    # PriorityAtJunction 46
    assert route_id(41, "Accident", 0) == str((41 * 100 + 0) * 10000 + 1)
    assert route_id(41, NO_SCENARIO, 0) == str((41 * 100 + 44) * 10000 + 1)
    assert route_id(41, "EnterActorFlowV2", 0) == str((41 * 100 + 45) * 10000 + 1)
    assert route_id(41, "PriorityAtJunction", 2) == str((41 * 100 + 46) * 10000 + 3)
    ids = {route_id(7, t, 0) for t in [s.xml_type for s in SCENARIO_TYPES] + [NO_SCENARIO, *NEW]}
    assert len(ids) == 47


def _route(rid: str, scenario: str) -> Route:
    config = ScenarioConfig(
        name=f"{scenario}_1", type=scenario, trigger_point=Transform(Location(1.0, 2.0, 0.0), Rotation(yaw=90.0)),
        other_parameters={"flow_speed": {"value": "18"}} if scenario == "EnterActorFlowV2" else {},
    )  # fmt: skip
    return Route(id=rid, town="Town12", waypoints=(Location(0.0, 0.0, 0.0), Location(0.0, 50.0, 0.0)),
                 scenarios=(config,))  # fmt: skip


def test_route_files_with_the_new_types_round_trip(tmp_path):
    routes = [_route("1", "EnterActorFlowV2"), _route("2", "PriorityAtJunction")]
    write_routes(routes, tmp_path / "r.xml")
    back = read_routes(tmp_path / "r.xml")
    assert [r.scenario_type for r in back] == list(NEW)
    assert back[0].scenarios[0].parameter("flow_speed") == "18"


def test_abilities_leave_the_new_types_out_without_failing():
    # routes 1 (Accident, success) and 2 (PriorityAtJunction, failed), 3 (EnterActorFlowV2, success) and
    # 4 (EnterActorFlowV2, never ran): only route 1 counts anywhere, Overtaking 1/1; no route of the new types enters
    # a denominator or the crashed list's ability bookkeeping, and nothing raises
    routes = [_route("1", "Accident"), _route("2", "PriorityAtJunction"), _route("3", "EnterActorFlowV2"),
              _route("4", "EnterActorFlowV2")]  # fmt: skip
    records = [
        RouteRecord(route_id="RouteScenario_1_rep0", status=STATUS_COMPLETED),
        RouteRecord(route_id="RouteScenario_2_rep0", status="Failed - Agent got blocked"),
        RouteRecord(route_id="RouteScenario_3_rep0", status=STATUS_COMPLETED),
    ]
    result = compute_abilities(records, routes)
    assert [(result.scores[a].successes, result.scores[a].routes, result.scores[a].routes_in_xml) for a in ABILITIES] == [
        (1, 1, 1), (0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0),
    ]  # fmt: skip
    assert result.crashed == [("EnterActorFlowV2", "4")]
    assert result.mean == 100.0  # Overtaking alone: the new types add no 0 % ability to the mean
    # a run of the new types only has no ability at all (no division by zero)
    only_new = compute_abilities(records[1:], routes[1:])
    assert only_new.mean is None and all(only_new.scores[a].value is None for a in ABILITIES)


def test_enter_actor_flow_v2_ranges_are_the_training_files_in_both_sets():
    from b2d_data.scenarios.param_ranges import BENCH2DRIVE220, TRAINING

    # routes_training.xml's 9 EnterActorFlowV2 scenarios (3 routes, each in 3 copies): flow_speed 18 / 22 / 15,
    # source_dist_interval 20-40 / 15-40 / 15-35 → flow_speed 15..22, from 15..20, to 35..40; PriorityAtJunction has
    # no parameter. Bench2Drive has no such route, so bench2drive220 uses the same ranges.
    for ranges in (TRAINING, BENCH2DRIVE220):
        spec = ranges.ranges("EnterActorFlowV2")
        assert (spec["flow_speed"].lo, spec["flow_speed"].hi) == (15, 22)
        interval = spec["source_dist_interval"]
        assert (interval.lo.lo, interval.lo.hi, interval.hi.lo, interval.hi.hi) == (15, 20, 35, 40)
        assert dict(ranges.ranges("PriorityAtJunction")) == {}
