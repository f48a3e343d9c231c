"""CollisionTest on synthetic collision events: typing, the 0.1 m/s rule and the 5 s / 5 m de-duplication."""

from __future__ import annotations

from b2d_data.format import leaderboard as lb
from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform, Vector3D
from b2d_data.format.weather import ROUTE_DEFAULT
from b2d_data.scenarios.criteria import CollisionTest
from b2d_data.sim.api import ActorKind, ActorState, CollisionEvent, Snapshot

EGO = 1


def ego_at(x: float, speed: float = 5.0) -> ActorState:
    return ActorState(
        id=EGO, type_id="vehicle.lincoln.mkz_2020", kind=ActorKind.VEHICLE,
        transform=Transform(Location(x, 2.0, 0.0), Rotation()), velocity=Vector3D(speed, 0.0, 0.0),
        angular_velocity=Vector3D(), acceleration=Vector3D(),
        bounding_box=BoundingBox(Location(0, 0, 0.75), Location(2.44, 1.06, 0.75)), semantic_tags=(14,),
        role_name="hero",
    )  # fmt: skip


def hit(frame: int, other_id: int, other_type: str, actor_id: int = EGO) -> CollisionEvent:
    return CollisionEvent(frame=frame, actor_id=actor_id, other_id=other_id, other_type_id=other_type,
                          location=Location(0.0, 0.0, 0.0))


def tick(test: CollisionTest, frame: int, ego: ActorState, *events: CollisionEvent) -> None:
    snap = Snapshot(frame=frame, timestamp=frame * 0.05, actors={EGO: ego}, traffic_lights={}, traffic_signs={},
                    collisions=events, weather=ROUTE_DEFAULT)
    test.update(snap, ego)


def test_one_vehicle_collision_is_one_event_with_the_leaderboard_message():
    test = CollisionTest(EGO)
    tick(test, 1, ego_at(10.0), hit(1, 42, "vehicle.tesla.model3"))
    assert test.failed
    assert [(e.key, e.message) for e in test.events] == [
        (lb.COLLISIONS_VEHICLE,
         "Agent collided against object with type=vehicle.tesla.model3 and id=42 at (x=10.0, y=2.0, z=0.0)"),
    ]


def test_types_walker_layout_and_ignored():
    test = CollisionTest(EGO)
    tick(test, 1, ego_at(0.0), hit(1, 7, "walker.pedestrian.0001"))
    tick(test, 500, ego_at(50.0), hit(500, 8, "static.prop.streetbarrier"))
    tick(test, 1000, ego_at(100.0), hit(1000, 9, "traffic.traffic_light"))
    tick(test, 1500, ego_at(150.0), hit(1500, 10, "static.sidewalk"))  # sidewalk: not layout, no event
    assert [e.key for e in test.events] == [lb.COLLISIONS_PEDESTRIAN, lb.COLLISIONS_LAYOUT, lb.COLLISIONS_LAYOUT]
    # The ignored type still counted as a collision for the de-duplication: a hit 1 m further is dropped.
    tick(test, 1501, ego_at(151.0), hit(1501, 11, "vehicle.audi.tt"))
    assert len(test.events) == 3 and test.actual_value == 4


def test_standing_ego_is_never_at_fault():
    test = CollisionTest(EGO)
    tick(test, 1, ego_at(0.0, speed=0.05), hit(1, 42, "vehicle.tesla.model3"))
    assert not test.events and not test.failed
    # Ignored hits do not arm the filters: the same actor hitting a moving ego next tick counts.
    tick(test, 2, ego_at(0.1, speed=3.0), hit(2, 42, "vehicle.tesla.model3"))
    assert len(test.events) == 1


def test_continued_contact_counts_once():
    test = CollisionTest(EGO)
    for frame in range(1, 21):  # one second pushing against the same car, 0.1 m per tick
        tick(test, frame, ego_at(frame * 0.1), hit(frame, 42, "vehicle.tesla.model3"))
    assert len(test.events) == 1


def test_same_actor_within_5_s_counts_once_even_far_away():
    test = CollisionTest(EGO)
    tick(test, 1, ego_at(0.0), hit(1, 42, "vehicle.tesla.model3"))
    tick(test, 41, ego_at(20.0), hit(41, 42, "vehicle.tesla.model3"))  # 2 s later, 20 m away: same id
    assert len(test.events) == 1
    tick(test, 202, ego_at(40.0))  # 10 s after the first hit the id filter has expired
    tick(test, 203, ego_at(41.0), hit(203, 42, "vehicle.tesla.model3"))
    assert len(test.events) == 2


def test_other_actor_within_5_m_of_the_last_collision_counts_once():
    test = CollisionTest(EGO)
    tick(test, 1, ego_at(0.0), hit(1, 42, "vehicle.tesla.model3"))
    tick(test, 2, ego_at(4.0), hit(2, 43, "vehicle.audi.tt"))  # 4 m on: same collision
    assert len(test.events) == 1
    tick(test, 3, ego_at(6.0))  # 6 m on: the location filter expires
    tick(test, 4, ego_at(6.5), hit(4, 43, "vehicle.audi.tt"))
    assert [e.actor_id for e in test.events] == [42, 43]


def test_collisions_of_other_actors_are_not_the_egos():
    test = CollisionTest(EGO)
    tick(test, 1, ego_at(0.0), hit(1, 42, "vehicle.tesla.model3", actor_id=5))
    assert not test.events
