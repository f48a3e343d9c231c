"""Issue 23 row 8: DynamicObjectCrossing, ParkingCutIn and StaticCutIn place their actors as scenario_runner's
``leaderboard-2.0`` branch (Bench2Drive ``da12001``) does where a junction lies ahead: they walk on through it and
accept a spot inside it.

Built on a hand-written road without a simulator: road 1 (x 0–100) and road 2 (x 120–420) heading east, each with
driving lanes -1 and -2 (3.5 m) and sidewalk -3 (2 m), joined by junction 100's connecting road 3 (x 100–120) with
the same three lanes.
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import LaneType, load_opendrive
from b2d_data.scenarios.catalog.road_geometry import lane_walk
from b2d_data.scenarios.framework import ScenarioContext, scenario_class
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import ScenarioConfig

EGO = 1
#: Lane -1's centre (CARLA y: OpenDRIVE's right is +y).
Y = 3.5 / 2.0


def _lane(lane_id: int, kind: str, width: float) -> str:
    return (f'<lane id="{lane_id}" type="{kind}" level="false">'
            f'<link><predecessor id="{lane_id}"/><successor id="{lane_id}"/></link>'
            f'<width sOffset="0" a="{width}" b="0" c="0" d="0"/>'
            '<roadMark sOffset="0" type="solid" color="white" width="0.15" laneChange="none"/></lane>')  # fmt: skip


def _road(road_id: int, x0: float, length: float, junction: int, link: str) -> str:
    lanes = _lane(-1, "driving", 3.5) + _lane(-2, "driving", 3.5) + _lane(-3, "sidewalk", 2.0)
    return (
        f'<road name="Road {road_id}" length="{length}" id="{road_id}" junction="{junction}">{link}'
        '<type s="0" type="town"><speed max="50" unit="km/h"/></type>'
        f'<planView><geometry s="0" x="{x0}" y="0" hdg="0" length="{length}"><line/></geometry></planView>'
        '<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>'
        '<lanes><laneOffset s="0" a="0" b="0" c="0" d="0"/><laneSection s="0">'
        f'<center><lane id="0" type="none" level="false"/></center><right>{lanes}</right></laneSection></lanes>'
        "</road>"
    )


def _junction_road() -> str:
    road_1 = _road(1, 0, 100, -1, '<link><successor elementType="junction" elementId="100"/></link>')
    road_3 = _road(3, 100, 20, 100, '<link><predecessor elementType="road" elementId="1" contactPoint="end"/>'
                                    '<successor elementType="road" elementId="2" contactPoint="start"/></link>')
    road_2 = _road(2, 120, 300, -1, '<link><predecessor elementType="junction" elementId="100"/></link>')
    junction = ('<junction id="100" name="J"><connection id="0" incomingRoad="1" connectingRoad="3" '
                'contactPoint="start"><laneLink from="-1" to="-1"/><laneLink from="-2" to="-2"/>'
                '<laneLink from="-3" to="-3"/></connection></junction>')  # fmt: skip
    return ('<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="4" name="Junction"/>'
            f"{road_1}{road_3}{road_2}{junction}</OpenDRIVE>")  # fmt: skip


@pytest.fixture(scope="module")
def town(tmp_path_factory):
    path = tmp_path_factory.mktemp("roads") / "Junction.xodr"
    path.write_text(_junction_road())
    return load_opendrive(path)


def build(town, scenario_type: str, trigger_x: float, **params: str):
    """``scenario_type`` triggered on lane -1 at x = ``trigger_x``, on a route along lane -1 from x = 2."""
    lane = lane_walk(town.get_waypoint(Location(2.0, Y, 0.0)), 410.0)
    dense = DenseRoute.from_pairs([(wp, RoadOption.LANEFOLLOW) for wp in lane], town)
    config = ScenarioConfig(f"{scenario_type}_1", scenario_type,
                            Transform(Location(trigger_x, Y, 0.0), Rotation(yaw=0.0)),
                            {tag: {"value": value} for tag, value in params.items()})  # fmt: skip
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
    return scenario_class(scenario_type)(ctx)


def _at(wp, road: int, lane: int, x: float) -> None:
    assert (wp.road_id, wp.lane_id) == (road, lane)
    assert wp.transform.location.x == pytest.approx(x, abs=0.05)


@pytest.mark.parametrize(("distance", "x"), [("18", 108.0), ("18.5", 109.0)])
def test_dynamic_object_crossing_walks_into_the_junction(town, distance, x):
    # object_crash_vehicle.py _initialize_actors: get_location_in_distance_from_wp(reference_wp, distance, False)
    # takes 1 m steps through junctions until the steps add up to `distance` (18.5: 19 steps), then
    # get_waypoint(location): from x = 90, x = 108 / 109, inside junction 100 on connecting road 3's lane -1. The
    # sidewalk walk goes right over lane -2 to sidewalk -3, whose centre is 1.75 + 3.5 + 1.0 = 6.25 m right of
    # lane -1's. (We refused a spot inside a junction, and walked 18.5 m.)
    scenario = build(town, "DynamicObjectCrossing", 90.0, distance=distance)
    _at(scenario.lane_waypoint, 3, -1, x)
    assert scenario.lane_waypoint.is_junction
    assert scenario.has_sidewalk and scenario.blocker_lateral == pytest.approx(6.25)


def test_parking_cut_in_spots_inside_a_junction(town):
    # parking_cut_in.py _initialize_actors: blocker at reference_wp.next(28)[0], cut-in car at next(35)[0], each on
    # the lane to the right (get_right_lane, any type). From x = 80: x = 108 and 115, both inside junction 100, on
    # connecting road 3 whose lane -2 lies right of lane -1. (We refused both.)
    scenario = build(town, "ParkingCutIn", 80.0, direction="right")
    for (lane, side), x in zip(scenario.slots, (108.0, 115.0), strict=True):
        _at(lane, 3, -1, x)
        _at(side, 3, -2, x)
        assert lane.is_junction


def test_static_cut_in_queue_through_a_junction(town):
    # cut_in_with_static_vehicle.py _initialize_actors: blocker_wp = reference_wp.next(distance)[0]; each of the 2
    # back cars, the cut-in car and the 3 front cars stands on blocker_wp.get_right_lane() (any lane), blocker_wp
    # then moving next(11)[0]; the cut-in car's point (_collision_wp) is the third. From x = 20 with distance 85:
    # x = 105, 116 (inside junction 100, road 3), 127, 138, 149, 160 (road 2), all on lane -2; the cut-in point is
    # lane -1 at x = 127. (We walked the side lane and refused a queue reaching into a junction.)
    scenario = build(town, "StaticCutIn", 20.0, direction="right", distance="85")
    xs = (105.0, 116.0, 127.0, 138.0, 149.0, 160.0)
    roads = (3, 3, 2, 2, 2, 2)
    for spot, x, road in zip(scenario.spots, xs, roads, strict=True):
        _at(spot, road, -2, x)
        assert spot.lane_type & LaneType.DRIVING
    _at(scenario.ego_lane, 2, -1, 127.0)
    assert scenario.cut_in_lateral == pytest.approx(3.5)
