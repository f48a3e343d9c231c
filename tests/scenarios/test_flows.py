"""Actor flows (catalog/flows.py): constant-velocity cars ignore vehicles until the flow's first collision (LB2.0's
``ActorFlow``), then brake for vehicles; bicycle flows ignore vehicles for good (LB2.0's ``BicycleFlow``).

Every flow runs on a straight generated lane (waypoints 1 m apart) at 8 m/s, i.e. 0.4 m per 0.05 s tick; the
obstacle stands at lane metre 40 (the ego: 30). Expected contact ticks are worked out by hand from the boxes.
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.rig import EGO_TYPE_ID
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios.catalog.flows import ActorFlow
from b2d_data.scenarios.catalog.road_geometry import heading_change, lane_walk
from b2d_data.scenarios.controllers import ConstantVelocityAgent, PathTrack
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorSpec, Snapshot
from b2d_data.sim.builtin.world import BuiltinSimulator

SPEED = 8.0
STEP = SPEED * 0.05  # m per tick
CAR = "vehicle.audi.a2"
CAR_HALF = blueprints.find(CAR).bounding_box.extent.x  # 1.8527 m
EGO_HALF_WIDTH = blueprints.find(EGO_TYPE_ID).bounding_box.extent.y  # 1.064 m
BIKE = "vehicle.bh.crossbike"
BIKE_HALF = blueprints.find(BIKE).bounding_box.extent.x  # 0.7547 m


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


@pytest.fixture(scope="module")
def lane(town):
    """A driving lane with 80 m of straight lane ahead (81 waypoints 1 m apart)."""
    for wp in town.generate_waypoints(20.0):
        if wp.is_junction:
            continue
        ahead = lane_walk(wp, 80.0)
        if len(ahead) > 80 and not any(w.is_junction for w in ahead) and heading_change(ahead) < 2.0:
            return ahead[:81]
    pytest.fail("the generated town has no straight 80 m lane")


def _park(sim: BuiltinSimulator, wp, type_id: str = CAR, role: str = "scenario", yaw_offset: float = 0.0) -> int:
    t = wp.transform
    rot = Rotation(pitch=t.rotation.pitch, yaw=t.rotation.yaw + yaw_offset, roll=t.rotation.roll)
    return sim.spawn_actor(ActorSpec(type_id, role_name=role),
                           Transform(Location(t.location.x, t.location.y, t.location.z + 0.2), rot))  # fmt: skip


def _first_contact(snap: Snapshot, actor_id: int) -> int | None:
    """The other actor of ``actor_id``'s collision this tick (None: none)."""
    return next((c.other_id for c in snap.collisions if c.actor_id == actor_id), None)


def _run(sim: BuiltinSimulator, flow: ActorFlow, ticks: int) -> list[Snapshot]:
    flow.start()
    snap = sim.tick()
    out = []
    for _ in range(ticks):
        flow.update(snap)
        snap = sim.tick()
        out.append(snap)
    return out


def _contact_tick(snaps: list[Snapshot], actor_id: int) -> tuple[int, int]:
    """(index in ``snaps``, other actor) of the first collision of ``actor_id``."""
    for k, snap in enumerate(snaps):
        other = _first_contact(snap, actor_id)
        if other is not None:
            return k, other
    pytest.fail(f"actor {actor_id} never collided")


def test_flow_car_keeps_its_speed_into_a_parked_car_then_the_flow_brakes_for_vehicles(town, lane):
    with BuiltinSimulator(town, seed=0) as sim:
        parked = _park(sim, lane[40])
        flow = ActorFlow(sim, np.random.default_rng(0), lane, SPEED, (15.0, 15.0), blueprint_ids=[CAR])
        snaps = _run(sim, flow, 220)
        first, second = flow.vehicles[0].actor_id, flow.vehicles[1].actor_id
        k, other = _contact_tick(snaps, first)
        # the front (s + 1.853) meets the parked car's rear (40 - 1.853) at s = 36.29 m: 36.29 / 0.4 = 90.7 → the
        # 91st tick after the spawn (index 90)
        assert other == parked
        assert k == pytest.approx((40.0 - 2.0 * CAR_HALF) / STEP, abs=1.0)
        # never slowed down for the car standing in its lane: 8 ± 0.1 m/s up to the contact tick
        speeds = [s.actors[first].speed() for s in snaps[: k + 1]]
        assert min(speeds) == pytest.approx(SPEED, abs=0.1) and max(speeds) == pytest.approx(SPEED, abs=0.1)
        assert flow.yielding
        # after it: the crashed car stays against the parked one (the simulator does not let it through) ...
        assert all(s.actors[first].speed() < 0.1 for s in snaps[k + 2 :])
        # ... and the car 15 m behind, now braking for vehicles, stops 2 m short of it (its stop gap), unhurt
        assert all(_first_contact(s, second) is None for s in snaps)
        end = snaps[-1]
        bumper = end.actors[first].location.distance_2d(end.actors[second].location) - 2.0 * CAR_HALF
        assert end.actors[second].speed() < 0.1
        assert bumper == pytest.approx(2.0, abs=0.5)
        # the cars spawned after the collision brake for vehicles too
        assert all(isinstance(v.agent, ConstantVelocityAgent) and v.agent.detect_vehicles for v in flow.vehicles)


def test_flow_car_drives_into_an_ego_standing_across_its_path(town, lane):
    with BuiltinSimulator(town, seed=0) as sim:
        ego = _park(sim, lane[30], EGO_TYPE_ID, role="hero", yaw_offset=90.0)
        flow = ActorFlow(sim, np.random.default_rng(0), lane, SPEED, (200.0, 200.0), blueprint_ids=[CAR])
        snaps = _run(sim, flow, 100)
        car = flow.vehicles[0].actor_id
        k, other = _contact_tick(snaps, car)
        # the front (s + 1.853) meets the ego's side (30 - 1.064) at s = 27.08 m: 27.08 / 0.4 = 67.7 → index 67
        assert other == ego
        assert k == pytest.approx((30.0 - EGO_HALF_WIDTH - CAR_HALF) / STEP, abs=1.0)
        speeds = [s.actors[car].speed() for s in snaps[: k + 1]]
        assert min(speeds) == pytest.approx(SPEED, abs=0.1) and max(speeds) == pytest.approx(SPEED, abs=0.1)
        assert flow.yielding and flow.vehicles[0].agent.detect_vehicles


def test_bicycle_flow_ignores_vehicles_after_a_collision_too(town, lane):
    with BuiltinSimulator(town, seed=0) as sim:
        parked = _park(sim, lane[40])
        flow = ActorFlow(sim, np.random.default_rng(0), lane, SPEED, (15.0, 15.0), blueprint_ids=[BIKE],
                         yield_after_collision=False)  # fmt: skip
        snaps = _run(sim, flow, 160)
        first, second = flow.vehicles[0].actor_id, flow.vehicles[1].actor_id
        k1, other1 = _contact_tick(snaps, first)
        # the bike's front (s + 0.755) meets the car's rear (40 - 1.853) at s = 37.39 m: 93.5 → index 93
        assert other1 == parked
        assert k1 == pytest.approx((40.0 - CAR_HALF - BIKE_HALF) / STEP, abs=1.0)
        assert not flow.yielding
        k2, other2 = _contact_tick(snaps, second)
        # the second bike keeps 8 ± 0.1 m/s, after the first one's collision too, until it rides into it
        assert other2 == first and k2 > k1
        speeds = [s.actors[second].speed() for s in snaps[: k2 + 1] if second in s.actors]
        assert min(speeds) == pytest.approx(SPEED, abs=0.1) and max(speeds) == pytest.approx(SPEED, abs=0.1)


def test_path_track_of_the_lane_is_straight(lane):
    # the hand-worked contact ticks above read lane metre k as waypoint k
    track = PathTrack.from_waypoints(lane)
    assert track.length == pytest.approx(80.0, abs=0.5)


def test_flow_gives_each_car_its_path_ahead(town, lane):
    """What FlowScenario hints the expert: a car 12 m down the lane (30 ticks × 0.4 m) gets the lane from its
    segment on, at least 40 m long; the lane's waypoints are 1 m apart, so that is ≥ 41 points starting ≤ 1 m
    behind the car."""
    with BuiltinSimulator(town, seed=0) as sim:
        flow = ActorFlow(sim, np.random.default_rng(0), lane, SPEED, (200.0, 200.0), blueprint_ids=[CAR])
        snaps = _run(sim, flow, 30)
        car = flow.vehicles[0].actor_id
        paths = flow.paths_ahead(40.0)
        assert set(paths) == {car}
        here = snaps[-1].actors[car].location
        path = paths[car]
        ahead = float(np.hypot(*(path[-1] - path[0])))
        assert path.shape[1] == 2 and path.shape[0] >= 41 and ahead >= 40.0
        start = lane[0].transform.location
        along_car = float(np.hypot(here.x - start.x, here.y - start.y))
        along_path = float(np.hypot(path[0, 0] - start.x, path[0, 1] - start.y))
        assert along_car - 1.5 <= along_path <= along_car + 0.01
