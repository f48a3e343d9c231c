"""``direction=left`` of the four kerb-side types on the downtown preset's one-way streets (Town104, seed 0).

Town104's one-way cross-section, from the left kerb (every lane right of the reference line): lane -1 sidewalk
3.29 m, -2 parking 2.23 m, -3 and -4 driving 3.48 m, -5 parking, -6 sidewalk (seed 0's widths). The leftmost
driving lane is -3; the parking lane on its left is -2 (same side of the reference line: it runs the ego's way) and
the sidewalk -1 beyond it. Lane centres from lane -3's: parking -(3.48 / 2 + 2.23 / 2) = -2.855 m, sidewalk
-(3.48 / 2 + 2.23 + 3.29 / 2) = -5.615 m (negative: left).
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.maps import LaneType, Map, load_opendrive
from b2d_data.maps.towngen import write_town
from b2d_data.scenarios import placement
from b2d_data.scenarios.catalog.road_geometry import lateral_offset
from b2d_data.scenarios.framework import ScenarioContext, scenario_class
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import Route

KERB_TYPES = ("DynamicObjectCrossing", "ParkingCrossingPedestrian", "ParkingCutIn", "ParkingExit")
PARKING_CENTRE = -(3.48 / 2 + 2.23 / 2)
SIDEWALK_CENTRE = -(3.48 / 2 + 2.23 + 3.29 / 2)


@pytest.fixture(scope="module")
def downtown(tmp_path_factory: pytest.TempPathFactory) -> Map:
    return load_opendrive(write_town("downtown", 0, tmp_path_factory.mktemp("towns")))


@pytest.fixture(scope="module")
def town100(tmp_path_factory: pytest.TempPathFactory) -> Map:
    return load_opendrive(write_town("all", 0, tmp_path_factory.mktemp("towns")))


def _set_up(town: Map, route: Route):
    """The route's scenario built as the placement checks it (no simulator)."""
    config = route.scenarios[0]
    dense = DenseRoute.from_keypoints(town, route.waypoints)
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config, rng=np.random.default_rng(0), ego_id=-1)
    return scenario_class(config.type)(ctx)  # type: ignore[arg-type]


def _one_way_leftmost(town: Map, scenario) -> None:
    wp = scenario.trigger_waypoint
    assert not wp.is_junction and wp.lane_id == -3 and wp.lane_type & LaneType.DRIVING
    # a one-way road: nothing across the reference line
    assert wp.get_left_lane().lane_id == -2 and wp.get_left_lane().get_left_lane().lane_id == -1


@pytest.mark.parametrize("scenario_type", KERB_TYPES)
def test_left_routes_place_on_the_one_way_left_kerb(downtown: Map, scenario_type: str) -> None:
    routes = placement.make_routes(downtown, scenario_type, 2, 0, direction="left")
    assert len(routes) == 2
    for route in routes:
        assert route.town == "Town104" and route.scenarios[0].parameter("direction") == "left"
        scenario = _set_up(downtown, route)
        _one_way_leftmost(downtown, scenario)
        if scenario_type == "DynamicObjectCrossing":
            # blocker and pedestrian on the left sidewalk's centre, abreast of the lane point
            assert scenario.lane_waypoint.lane_id == -3 and scenario.has_sidewalk
            assert scenario.blocker_lateral == pytest.approx(SIDEWALK_CENTRE, abs=0.01)
        elif scenario_type == "ParkingCrossingPedestrian":
            # the car in the left parking lane, the walker stepping out from that lane's centre
            assert scenario.parking is not None and scenario.parking.lane_id == -2
            assert scenario.parking.lane_type & LaneType.PARKING
            assert scenario.walker_lateral == pytest.approx(PARKING_CENTRE, abs=0.01)
        elif scenario_type == "ParkingCutIn":
            # both parked cars (blocker, cut-in car) in the left parking lane
            for lane, parking in scenario.slots:
                assert lane.lane_id == -3 and parking.lane_id == -2 and parking.lane_type & LaneType.PARKING
                assert lateral_offset(lane, parking) == pytest.approx(PARKING_CENTRE, abs=0.01)
            assert scenario.cut_in_lateral < PARKING_CENTRE  # pushed further out, toward the kerb
        else:
            # the ego's slot and the cars before and after it in the left parking lane
            assert scenario.parking.lane_id == -2 and scenario.parking.lane_type & LaneType.PARKING
            assert lateral_offset(scenario.reference, scenario.parking) == pytest.approx(PARKING_CENTRE, abs=0.01)
            assert all(slot.lane_id == -2 for slot in scenario._parked_slots)


@pytest.mark.parametrize("scenario_type", KERB_TYPES)
def test_a_two_way_town_has_no_left_kerb_and_says_so(
    town100: Map, scenario_type: str, caplog: pytest.LogCaptureFixture
) -> None:
    assert placement.missing_sides(town100, scenario_type) == ("left",)
    with pytest.raises(placement.PlacementError):
        placement.make_routes(town100, scenario_type, 1, 0, direction="left")
    with caplog.at_level("WARNING", logger="b2d_data.scenarios.placement"):
        routes = placement.make_routes(town100, scenario_type, 1, 0)
    assert routes[0].scenarios[0].parameter("direction") == "right"
    assert f"Town100 has no place for {scenario_type} with direction=left" in caplog.text


def test_downtown_holds_both_sides(downtown: Map) -> None:
    for scenario_type in KERB_TYPES:
        assert placement.missing_sides(downtown, scenario_type) == ()
