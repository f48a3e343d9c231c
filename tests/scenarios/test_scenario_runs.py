"""Every implemented scenario builds, triggers and runs to its end in the builtin simulator.

A scripted ego moves along the dense route at 8 m/s (teleported point by point, so that it drives through the
obstacles it does not avoid); then one route per family is driven closed loop by the expert through the route
runner, with the leaderboard's 4000-tick limit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from b2d_data.format import leaderboard as lb
from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform, Vector3D
from b2d_data.maps import LaneType, load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.framework import SCENARIO_ROLE, ScenarioContext, ScenarioManager, ScenarioStatus
from b2d_data.scenarios.placement import make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_runner import RouteRunner
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorKind, ActorSpec, TrafficLightState
from b2d_data.sim.builtin.world import BuiltinSimulator

TYPES = (
    "Accident", "ParkedObstacleTwoWays", "HazardAtSideLane", "HardBreakRoute", "DynamicObjectCrossing",
    "OppositeVehicleRunningRedLight", "SignalizedJunctionLeftTurn", "NonSignalizedJunctionRightTurn",
    "YieldToEmergencyVehicle", "VanillaSignalizedTurnEncounterRedLight", "VanillaNonSignalizedTurnEncounterStopsign",
    "ParkingExit", "NonSignalizedJunctionLeftTurn", "SignalizedJunctionRightTurn",
    "SignalizedJunctionLeftTurnEnterFlow", "NonSignalizedJunctionLeftTurnEnterFlow", "EnterActorFlow",
    "CrossingBicycleFlow",
)  # fmt: skip
#: Scenarios whose flow of vehicles crosses the route's junction.
FLOWS = (
    "SignalizedJunctionLeftTurn", "NonSignalizedJunctionRightTurn", "NonSignalizedJunctionLeftTurn",
    "SignalizedJunctionRightTurn", "SignalizedJunctionLeftTurnEnterFlow", "NonSignalizedJunctionLeftTurnEnterFlow",
    "EnterActorFlow", "CrossingBicycleFlow",
)  # fmt: skip
#: Scenarios whose flow drives into the road the ego leaves the junction on.
INTO_EGO_EXIT = ("SignalizedJunctionLeftTurnEnterFlow", "NonSignalizedJunctionLeftTurnEnterFlow", "EnterActorFlow")
OBSTACLES = ("Accident", "ParkedObstacleTwoWays", "HazardAtSideLane")


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


@dataclass
class Trace:
    """What a scripted run saw."""

    statuses: dict
    events: list
    hints_valid: bool = True
    hint_types: set = field(default_factory=set)
    scenario_vehicles: set = field(default_factory=set)
    scenario_walkers: set = field(default_factory=set)
    max_scenario_speed: float = 0.0
    ego_after_build: Location | None = None
    ego_light_states: list = field(default_factory=list)
    leftover: int = 0
    ticks: int = 0
    #: (type_id, road_id, lane_type, in a junction) of the scenario vehicles, sampled every 5 ticks
    scenario_places: set = field(default_factory=set)


def run_scripted(town, route, speed: float = 8.0, max_ticks: int = 1600) -> Trace:
    dense = DenseRoute.from_route(town, route)
    with BuiltinSimulator(town, seed=0) as sim:
        first = dense.waypoints[0].transform
        ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), Transform(
            Location(first.location.x, first.location.y, first.location.z + 0.5), first.rotation))  # fmt: skip
        snap = sim.tick()
        sim.background.start(ego, list(dense.waypoints))
        manager = ScenarioManager(lambda cfg: ScenarioContext(sim, town, dense, cfg, np.random.default_rng(1), ego),
                                  route.scenarios)  # fmt: skip
        trace = Trace(statuses={}, events=[])
        s_along, index = 0.0, 0
        for tick in range(max_ticks):
            index = dense.closest_index(snap.actors[ego].location, max(0, index - 2), 10)
            manager.tick(snap, index)
            for hint in manager.hints():
                trace.hint_types.add(hint.scenario_type)
                for actor_id in (hint.first_actor_id, hint.last_actor_id):
                    if actor_id is not None and actor_id not in sim.actor_ids():
                        trace.hints_valid = False
            if tick > 0:  # the first tick shows where the scenario's build put the ego
                s_along = min(s_along + speed * 0.05, dense.total_length)
                k = min(int(np.searchsorted(dense.cumulative_length, s_along)), len(dense) - 1)
                t = dense.waypoints[k].transform
                sim.set_transform(ego, Transform(Location(t.location.x, t.location.y, t.location.z + 0.1), t.rotation))
                # report the speed too (time-to-arrival triggers read it); the next teleport undoes the extra step
                f = t.get_forward_vector()
                sim.set_target_velocity(ego, Vector3D(f.x * speed, f.y * speed, 0.0))
            snap = sim.tick()
            if tick == 0:
                trace.ego_after_build = snap.actors[ego].location
            for a in snap.actors.values():
                if a.role_name == SCENARIO_ROLE:
                    (trace.scenario_walkers if a.kind is ActorKind.WALKER else trace.scenario_vehicles).add(a.id)
                    trace.max_scenario_speed = max(trace.max_scenario_speed, a.speed())
                    if a.kind is ActorKind.VEHICLE and tick % 5 == 0:
                        wp = town.get_waypoint(a.location, lane_type=LaneType.DRIVING | LaneType.BIKING)
                        trace.scenario_places.add((a.type_id, wp.road_id, wp.lane_type, wp.is_junction))
            lights = [i for i in snap.traffic_lights.values()
                      if any(w.road_id == dense.waypoints[index].road_id for w in i.stop_waypoints)]  # fmt: skip
            trace.ego_light_states.append(tuple(sorted(i.state for i in lights)))
            if all(v is not None for v in manager.statuses.values()):
                break
        manager.cleanup(snap)
        trace.statuses, trace.events, trace.ticks = manager.statuses, manager.events, tick
        trace.leftover = sum(1 for a in sim.tick().actors.values() if a.role_name == SCENARIO_ROLE)
    return trace


@pytest.mark.parametrize("scenario_type", TYPES)
def test_scenario_runs_to_its_end_with_a_scripted_ego(town, scenario_type):
    route = make_routes(town, scenario_type, 1, seed=0)[0]
    # slower through the merges, so that the flow (not pre-populated) reaches the exit road before the ego left
    trace = run_scripted(town, route, speed=3.0 if scenario_type in INTO_EGO_EXIT else 8.0)
    assert list(trace.statuses.values()) == [ScenarioStatus.SUCCESS], trace.statuses
    assert trace.leftover == 0  # cleanup removed every scenario actor
    assert trace.hints_valid
    if scenario_type in OBSTACLES:
        assert trace.hint_types == {scenario_type}
    if scenario_type == "YieldToEmergencyVehicle":
        # the scripted ego never leaves its lane: the emergency vehicle ends behind it
        assert trace.hint_types == {scenario_type}
        assert [(e.key, e.message) for e in trace.events] == [
            (lb.YIELD_EMERGENCY_VEHICLE, "Agent failed to yield to an emergency vehicle")
        ]
    else:
        assert trace.events == []
    if scenario_type == "DynamicObjectCrossing":
        assert len(trace.scenario_walkers) == 1
    if scenario_type == "OppositeVehicleRunningRedLight":
        assert trace.max_scenario_speed == pytest.approx(60 / 3.6, abs=0.3)
    if scenario_type in FLOWS:
        assert len(trace.scenario_vehicles) >= 3  # a flow
        assert any(in_junction for *_, in_junction in trace.scenario_places)  # that crosses the junction
    if scenario_type in INTO_EGO_EXIT:
        dense = DenseRoute.from_route(town, route)
        inside = next(k for k, wp in enumerate(dense.waypoints) if wp.is_junction)
        exit_road = next(wp.road_id for wp in dense.waypoints[inside:] if not wp.is_junction)
        assert exit_road in {road for _, road, _, in_junction in trace.scenario_places if not in_junction}
    if scenario_type == "CrossingBicycleFlow":
        # bicycles (CARLA's bicycle blueprints, with their riders), riding the bike lane through the junction
        assert {blueprints.find(t).base_type for t, *_ in trace.scenario_places} == {"bicycle"}
        assert any(
            lane_type & LaneType.BIKING and in_junction for _, _, lane_type, in_junction in trace.scenario_places
        )
    if scenario_type == "VanillaSignalizedTurnEncounterRedLight":
        seen = [s for s in trace.ego_light_states if s]
        assert (TrafficLightState.RED,) in seen and any(TrafficLightState.GREEN in s for s in seen)
    if scenario_type == "ParkingExit":
        parking = town.get_waypoint(trace.ego_after_build, lane_type=LaneType.PARKING)
        assert parking is not None and parking.transform.location.distance_2d(trace.ego_after_build) < 1.5


EXPERT_SMOKE = ("Accident", "DynamicObjectCrossing", "NonSignalizedJunctionRightTurn", "YieldToEmergencyVehicle")


@pytest.mark.parametrize("scenario_type", EXPERT_SMOKE)
def test_the_expert_completes_one_route_per_family(town, scenario_type):
    from b2d_data import expert
    route = make_routes(town, scenario_type, 1, seed=0)[0]
    dense = DenseRoute.from_route(town, route)
    with BuiltinSimulator(town, seed=0) as sim:
        result = RouteRunner(sim, route, expert.Expert(town, list(dense), seed=0), seed=0, dense_route=dense,
                             max_ticks=4000).run()  # fmt: skip
    infractions = {k: v for k, v in result.record.infractions.items() if v and k != lb.MIN_SPEED_INFRACTIONS}
    assert result.success, (result.record.status, infractions)
