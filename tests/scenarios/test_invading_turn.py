"""InvadingTurn's flow waits while the ego is at its source (our departure), and the scenario's LB2.0 end condition.

The flow of ``scenarios/catalog/flows.py`` spawns at its source whenever the last car is a gap away (LB2.0's
InvadingActorFlow rule); InvadingTurn alone adds ``hero_clearance``: no car appears while the hero is within 15 m of
the source. Distances below are measured along straight generated lanes, where they equal the 2D distance.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Transform
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.flows import ActorFlow
from b2d_data.scenarios.catalog.invading_turn import InvadingTurn
from b2d_data.scenarios.catalog.road_geometry import heading_change, lane_walk, move_along
from b2d_data.scenarios.framework import ScenarioContext, ScenarioManager, ScenarioStatus
from b2d_data.scenarios.placement import make_routes
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.triggers import trigger_route_index
from b2d_data.sim.api import ActorSpec
from b2d_data.sim.builtin.world import BuiltinSimulator


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def _straight_stretch(town, length: float = 60.0):
    """Lane waypoints 1 m apart over ``length`` m that turn by less than 0.5°, with ≥ 20 m of straight lane behind."""
    for wp in town.generate_waypoints(5.0):
        if wp.is_junction:
            continue
        back = lane_walk(wp, 20.0, forward=False)
        ahead = lane_walk(wp, length)
        if (
            len(back) == 21
            and len(ahead) == int(length) + 1
            and not any(w.is_junction for w in back + ahead)
            and heading_change(list(reversed(back)) + ahead[1:]) < 0.5
        ):
            return back, ahead
    raise AssertionError("the generated town has no straight 80 m stretch")


def _pose(wp, z: float = 0.5) -> Transform:
    loc = wp.transform.location
    return Transform(Location(loc.x, loc.y, loc.z + z), wp.transform.rotation)


@pytest.mark.parametrize(("clearance", "behind", "spawns"), [
    (15.0, 14, False),  # the ego 14 m from the source, inside the 15 m: the car waits
    (15.0, 16, True),  # 16 m: outside, the car appears
    (None, 14, True),  # LB2.0's rule (every other flow): the ego's position does not matter
])  # fmt: skip
def test_the_flow_holds_its_car_back_while_the_hero_is_near_the_source(town, clearance, behind, spawns):
    back, path = _straight_stretch(town)
    with BuiltinSimulator(town, seed=0) as sim:
        # the hero stands `behind` m upstream of the source on the flow's own lane, out of the cars' way
        sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), _pose(back[behind]))
        flow = ActorFlow(sim, np.random.default_rng(0), path, 8.0, (40.0, 40.0), constant_velocity=False,
                         hero_clearance=clearance)  # fmt: skip
        flow.start()
        snap = sim.tick()
        hero = snap.hero()
        assert hero.location.distance_2d(path[0].transform.location) == pytest.approx(behind, abs=0.05)
        for _ in range(3):
            flow.update(snap)
            snap = sim.tick()
        assert len(flow.actor_ids) == (1 if spawns else 0)
        if not spawns:
            # the hero leaves: the first update with it 16 m away spawns the car
            sim.set_transform(hero.id, _pose(back[16]))
            snap = sim.tick()
            flow.update(snap)
            assert len(flow.actor_ids) == 1


def _started_invading_turn(town, sim):
    """InvadingTurn on the first generated route, triggered by an ego spawned at its trigger point."""
    route = make_routes(town, "InvadingTurn", 1, seed=0, params="bench2drive220")[0]
    dense = DenseRoute.from_route(town, route)
    rng = np.random.default_rng(1)
    index = trigger_route_index(dense, route.scenarios[0].trigger_point)
    ego = sim.spawn_actor(ActorSpec(EGO_TYPE_ID, role_name="hero"), _pose(dense.waypoints[index]))
    sim.background.start(ego, list(dense.waypoints))
    manager = ScenarioManager(lambda cfg: ScenarioContext(sim, town, dense, cfg, rng, ego), route.scenarios)
    snap = sim.tick()
    manager.tick(snap, index)
    (scenario,) = manager.scenarios
    assert isinstance(scenario, InvadingTurn) and manager.active == [scenario]
    return manager, scenario, ego, index


def test_only_invading_turn_holds_its_flow_and_it_ends_in_front_of_the_source_within_50_m(town):
    with BuiltinSimulator(town, seed=0) as sim:
        manager, scenario, ego, index = _started_invading_turn(town, sim)
        assert scenario.flow is not None and scenario.flow.hero_clearance == 15.0
        # every other flow is built without it, and the default keeps LB2.0's rule
        assert inspect.signature(ActorFlow).parameters["hero_clearance"].default is None
        source = scenario.source_reference
        # WaitUntilInFrontPosition(ego, forward_wp, check_distance=True, 50): in front of the point and within 50 m
        far = move_along(source, 55.0)
        if far is None:
            pytest.skip("the ego's lane ends within 55 m after the source")
        behind, near = move_along(source, 10.0, forward=False), move_along(source, 3.0)
        for where, running in ((behind, True), (far, True), (near, False)):
            sim.set_transform(ego, _pose(where))
            snap = sim.tick()
            manager.tick(snap, index)
            status = manager.statuses[scenario.name]
            assert (status is None) is running, (where.transform.location, status)
        assert list(manager.statuses.values()) == [ScenarioStatus.SUCCESS]
        manager.cleanup(snap)
