"""EnterActorFlowV2 as LB2.0's ``actor_flow.py`` runs it, placed on a generated town's on-ramp.

Reference (Bench2Drive's copy, identical to scenario_runner leaderboard-2.0), ``EnterActorFlowV2._create_behavior``
(:165-227) with EnterActorFlow's ``__init__`` (:67-94):

- ONE ActorFlow, on the lane of ``start_actor_flow`` only (EnterActorFlow runs one per lane), pre-populated;
- at the start ``HandleJunctionScenario(clear_junction=False, clear_ego_entry=True, remove_entries=[source_wp],
  remove_exits=get_same_dir_lanes(exit_wp), stop_entries=False, extend_road_exit=0)`` and ``SwitchRouteSources(False)``,
  where ``exit_wp`` is 10 m after the route's junction exit;
- once the ego has left a junction, ``HandleJunctionScenario`` again with only ``extend_road_exit`` = 20 m + the flow's
  metres from its last junction point to the sink;
- SUCCESS when the ego is within 2 m of the sink point of ANY same-direction lane at the sink.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog import enter_flow_v2
from b2d_data.scenarios.catalog.enter_flow_v2 import EnterActorFlowV2
from b2d_data.scenarios.catalog.road_geometry import same_direction_lanes
from b2d_data.scenarios.framework import SCENARIO_ROLE, ScenarioContext, ScenarioManager, ScenarioStatus
from b2d_data.scenarios.placement import find_candidates, make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.triggers import trigger_route_index
from b2d_data.sim.api import ActorKind, ActorSpec
from b2d_data.sim.builtin.world import BuiltinSimulator

TYPE = "EnterActorFlowV2"


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def _xml_wp(town, spot: dict):
    return town.get_waypoint(Location(*(float(spot[a]) for a in "xyz")))


def _at(wp) -> Transform:
    loc = wp.transform.location
    return Transform(Location(loc.x, loc.y, loc.z + 0.5), wp.transform.rotation)


def _key(wp) -> tuple[int, int]:
    return wp.road_id, wp.lane_id


def test_placement_puts_the_flow_on_the_highway_lane_beside_the_ramp_lane_the_route_merges_from(town):
    assert find_candidates(town, TYPE)
    for route in make_routes(town, TYPE, 3, seed=0):
        (config,) = route.scenarios
        params = config.other_parameters
        # training ranges (routes_training.xml: flow_speed 15-22, source_dist_interval 15-20 / 35-40)
        assert 15 <= int(params["flow_speed"]["value"]) <= 22
        assert 15 <= int(params["source_dist_interval"]["from"]) <= 20
        assert 35 <= int(params["source_dist_interval"]["to"]) <= 40
        dense = DenseRoute.from_route(town, route)
        source, sink = _xml_wp(town, params["start_actor_flow"]), _xml_wp(town, params["end_actor_flow"])
        route_lanes = [_key(wp) for wp in dense.waypoints]
        # the route starts on the ramp, not on the flow's lane, and ends up on the flow's lane at the sink
        assert route_lanes[0] != _key(source) and _key(sink) in route_lanes
        assert town.speed_limit(source) >= 80.0
        # the sink lies FLOW_AFTER m past the junction, the source up to FLOW_BACK m before it: ~60 + 40 + 110 m
        assert 150.0 < source.transform.location.distance_2d(sink.transform.location) < 230.0


def test_one_flow_on_the_source_lane_background_requests_and_the_end_at_any_lane_of_the_sink(town, monkeypatch):
    route = make_routes(town, TYPE, 1, seed=0)[0]
    dense = DenseRoute.from_route(town, route)
    (config,) = route.scenarios
    index = trigger_route_index(dense, config.trigger_point)
    calls: list[tuple[str, dict]] = []
    with BuiltinSimulator(town, seed=0) as sim:
        monkeypatch.setattr(sim.background, "handle_junction_scenario", lambda **k: calls.append(("junction", k)))
        monkeypatch.setattr(sim.background, "switch_route_sources", lambda on: calls.append(("sources", {"on": on})))
        ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), _at(dense.waypoints[index]))
        manager = ScenarioManager(lambda cfg: ScenarioContext(sim, town, dense, cfg, np.random.default_rng(1), ego),
                                  route.scenarios)  # fmt: skip
        (scenario,) = manager.scenarios
        assert isinstance(scenario, EnterActorFlowV2)
        snap = sim.tick()
        manager.tick(snap, index)  # build + trigger + start
        snap = sim.tick()
        cars = [a for a in snap.actors.values() if a.role_name == SCENARIO_ROLE and a.kind is ActorKind.VEHICLE]
        start_calls = list(calls)
        # the ego enters the junction, then leaves it: the second request
        inside = next(k for k in range(index, len(dense.waypoints)) if dense.waypoints[k].is_junction)
        after = next(k for k in range(inside, len(dense.waypoints)) if not dense.waypoints[k].is_junction) + 3
        for k in (inside + 2, after):
            sim.set_transform(ego, _at(dense.waypoints[k]))
            snap = sim.tick()
            manager.tick(snap, k)
        second = calls[len(start_calls) :]
        # 3 m from the sink point of a lane that is NOT the flow's: still running; 1.5 m from it: SUCCESS
        flow_lane = _key(scenario.path[-1])
        other = next(wp for wp in scenario.sinks if _key(wp) != flow_lane)
        statuses = []
        for back in (3.0, 1.5):
            yaw = math.radians(other.transform.rotation.yaw)
            loc = other.transform.location
            spot = Transform(Location(loc.x - back * math.cos(yaw), loc.y - back * math.sin(yaw), loc.z + 0.5),
                             other.transform.rotation)  # fmt: skip
            sim.set_transform(ego, spot)
            snap = sim.tick()
            manager.tick(snap, dense.closest_index(spot.location))
            statuses.append(manager.statuses[scenario.name])
    source = _xml_wp(town, config.other_parameters["start_actor_flow"])
    highway_lanes = same_direction_lanes(source)
    # at the start: the ego's entry kept clear, ONLY the flow's own lane removed from the junction's entries (V1
    # removes every lane of the flow's road), the lanes after the junction removed, no extension, sources off
    assert start_calls[0][0] == "junction" and start_calls[1] == ("sources", {"on": False})
    first = start_calls[0][1]
    assert (first["clear_junction"], first["clear_ego_entry"], first["stop_entries"]) == (False, True, False)
    assert first["extend_road_exit"] == 0.0
    assert [_key(wp) for wp in first["remove_entries"]] == [_key(source)] and len(highway_lanes) >= 2
    # remove_exits = get_same_dir_lanes(exit_wp) 10 m after the junction: the highway's lanes plus the entry's own
    exits = {_key(wp) for wp in first["remove_exits"]}
    assert len(exits) == len(highway_lanes) + 1
    assert _key(scenario.ego_exit) in exits and flow_lane in exits
    # one flow, every car of it on the flow's path, spaced by the XML's interval (pre-populated from the sink back)
    assert len(cars) >= 3
    path = np.array([[wp.transform.location.x, wp.transform.location.y] for wp in scenario.path])
    offsets = [np.hypot(path[:, 0] - c.location.x, path[:, 1] - c.location.y) for c in cars]
    assert max(float(d.min()) for d in offsets) < 1.5
    along = sorted(int(np.argmin(d)) for d in offsets)
    lo, hi = (float(config.other_parameters["source_dist_interval"][a]) for a in ("from", "to"))
    # the first car nearest the source was born there at the first update; the others pre-populate the path from the
    # sink back, a gap in [from, to] apart (path points 1 m apart; every car moved one tick, <= 1.1 m, since)
    assert along[0] <= 2
    gaps = np.diff(along[1:])
    assert gaps.min() >= lo - 1.5 and gaps.max() <= hi + 1.5
    # once out of the junction: only the road-exit extension, 20 m + the flow's metres after its junction; the sink is
    # FLOW_AFTER = 110 m past the highway lane's exit, itself the first point after the junction (<= 1 m on)
    assert [name for name, _ in second] == ["junction"]
    assert second[0][1] == {"extend_road_exit": scenario.extra_space}
    assert 20.0 + enter_flow_v2.FLOW_AFTER <= scenario.extra_space <= 20.0 + enter_flow_v2.FLOW_AFTER + 1.5
    # the end: within 2 m of any same-direction lane's sink point; 110 m after the junction the entry's own lane still
    # runs beside the highway (the town's acceleration lanes: 90-120 m full width, then a 60 m taper)
    assert len(scenario.sinks) == len(highway_lanes) + 1
    assert statuses == [None, ScenarioStatus.SUCCESS]


def test_expert_merges_into_the_fast_flow_from_the_ramp(tmp_path):
    from b2d_data import expert
    from b2d_data.collection.towns import TownSource, load_map
    from b2d_data.scenarios.route_runner import RouteRunner

    world_map = load_map(TownSource(preset="highway").materialise(tmp_path))
    route = make_routes(world_map, TYPE, 1, seed=0)[0]
    dense = DenseRoute.from_route(world_map, route)
    params = route.scenarios[0].other_parameters
    flow_lane = _key(_xml_wp(world_map, params["end_actor_flow"]))
    flow_speed = float(params["flow_speed"]["value"])
    ego_lanes: list[tuple[int, int]] = []
    flow_seen: list[tuple[tuple[int, int], float]] = []

    def on_frame(snapshot, info) -> None:
        ego_lanes.append(_key(world_map.get_waypoint(snapshot.actors[info.ego_id].location)))
        for a in snapshot.actors.values():
            if a.role_name == SCENARIO_ROLE and a.kind is ActorKind.VEHICLE:
                flow_seen.append((_key(world_map.get_waypoint(a.location)), a.speed()))

    with BuiltinSimulator(world_map, seed=0) as sim:
        result = RouteRunner(sim, route, expert.Expert(world_map, list(dense), seed=0), seed=0, dense_route=dense,
                             on_frame=on_frame, record_every=1, max_ticks=4000).run()  # fmt: skip
    infractions = {k: v for k, v in result.record.infractions.items() if v and k != "min_speed_infractions"}
    assert result.success, infractions
    # the ego came off the ramp and into the flow's lane; the flow drove at its XML speed
    assert ego_lanes[0] != flow_lane and flow_lane in ego_lanes
    assert flow_seen and max(speed for _, speed in flow_seen) == pytest.approx(flow_speed, abs=0.5)


def test_a_route_file_of_it_collects_one_clip_named_after_it_with_the_flow_annotated(tmp_path):
    """Route XML parsing and clip naming: b2d-collect --routes on a generated EnterActorFlowV2 route, cut short."""
    import gzip
    import json
    from dataclasses import replace

    from b2d_data.cli.collect import main
    from b2d_data.collection.towns import TownSource, load_map
    from b2d_data.scenarios.route_xml import write_routes

    town_src = TownSource(preset="all").materialise(tmp_path / "town")
    world_map = load_map(town_src)
    route = make_routes(world_map, TYPE, 1, seed=0)[0]
    start = route.waypoints[0]
    cut = replace(route, waypoints=tuple(p for p in route.waypoints if math.hypot(p.x - start.x, p.y - start.y) <= 120))
    write_routes([cut], tmp_path / "routes.xml")
    out = tmp_path / "data"
    tiny = ["--width", "64", "--height", "36", "--lidar-azimuth-steps", "90", "--encode-workers", "0", "--no-progress"]
    args = ["--routes", str(tmp_path / "routes.xml"), "--xodr", str(town_src.xodr), "--out", str(out), *tiny]
    assert main(args) == 0
    (clip,) = [p for p in out.iterdir() if p.is_dir() and (p / "anno").is_dir()]
    # Bench2Drive's clip-name style with the class name as prefix
    assert clip.name.startswith(f"{TYPE}_{world_map.name}_Route{route.id}_Weather")
    flow_lane = _key(_xml_wp(world_map, route.scenarios[0].other_parameters["start_actor_flow"]))
    boxes = []
    for path in sorted((clip / "anno").glob("*.json.gz")):
        with gzip.open(path, "rt", encoding="utf-8") as f:
            boxes += [b for b in json.load(f)["bounding_boxes"][1:] if b["class"] == "vehicle"]
    # the flow's lane is removed from background traffic at the trigger: cars annotated on it are the flow's
    on_lane = [b for b in boxes if (b["road_id"], b["lane_id"]) == flow_lane]
    assert on_lane and all(b["type_id"].startswith("vehicle.") for b in on_lane)
