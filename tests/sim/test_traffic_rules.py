"""The shared stop-sign rule (expert and RunningStopTest), on a straight lane of a real town."""

from __future__ import annotations

import pytest

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform
from b2d_data.maps import load_opendrive
from b2d_data.sim.api import TrafficSignInfo
from b2d_data.sim.traffic_rules import stop_affects, stop_trigger_centre, stop_zone_waypoints


@pytest.fixture(scope="module")
def town01(carla_maps_dir):
    return load_opendrive(carla_maps_dir / "Town01.xodr")


def _sign_at(location: Location, extent: Location) -> TrafficSignInfo:
    # The trigger volume sits 2 m in front of the sign's own origin (its local +x), here the world's −y side.
    return TrafficSignInfo(
        id=1, type_id="traffic.stop", transform=Transform(Location(location.x, location.y + 2.0, 0.0),
                                                          Rotation(yaw=-90.0)),
        trigger_volume=BoundingBox(Location(2.0, 0.0, 0.0), extent), level_bbox=BoundingBox(Location(), Location()),
        level_bbox_transform=Transform(),
    )  # fmt: skip


def test_stop_zone_and_affects(town01):
    # A waypoint with over 20 m of straight lane ahead, so the 4 m zone stays on one straight lane.
    wp = next(w for w in town01.generate_waypoints(50.0) if len(w.next_until_lane_end(0.5)) > 40)
    start = wp.transform.location
    zone = stop_zone_waypoints(town01, start)
    # 9 waypoints 0.5 m apart: the first one at the ego's lane position, the last 4 m on.
    assert len(zone) == 9
    assert zone[-1].transform.location.distance(start) == pytest.approx(4.0, abs=0.05)
    ahead = zone[4].transform.location  # 2 m along the lane
    sign = _sign_at(ahead, Location(1.0, 1.0, 1.0))
    assert stop_trigger_centre(sign).distance_2d(ahead) == pytest.approx(0.0, abs=1e-9)
    assert stop_affects(zone, sign)  # the centre is 2 m from the first waypoint and covers the one 2 m on
    far = zone[-1].transform.location
    fwd = zone[-1].transform.get_forward_vector()
    beyond = Location(far.x + 2.0 * fwd.x, far.y + 2.0 * fwd.y, far.z)  # 6 m from the first waypoint (> 4 m)
    assert not stop_affects(zone, _sign_at(beyond, Location(5.0, 5.0, 1.0)))
    assert not stop_affects([], sign)
