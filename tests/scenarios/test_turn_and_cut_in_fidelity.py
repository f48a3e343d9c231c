"""Issue 23 rows 23 and 24: InvadingTurn's cones and flow offset, HighwayCutIn's sync and cut-in, as
scenario_runner's ``leaderboard-2.0`` branch (Bench2Drive ``da12001``) has them.

Each test names the reference file and works out the expected value by hand from it. The scenarios are built on
small hand-written OpenDRIVE roads without a simulator where their constructors need only the map and the route.
"""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.road_option import RoadOption
from b2d_data.format.transform import Location, Rotation, Transform
from b2d_data.maps import load_opendrive
from b2d_data.scenarios.catalog.road_geometry import lane_walk
from b2d_data.scenarios.framework import ScenarioContext, scenario_class
from b2d_data.scenarios.route import DenseRoute
from b2d_data.scenarios.route_xml import ScenarioConfig

EGO = 1


def _lane(lane_id: int, kind: str, width: float) -> str:
    return (f'<lane id="{lane_id}" type="{kind}" level="false">'
            f'<link><predecessor id="{lane_id}"/><successor id="{lane_id}"/></link>'
            f'<width sOffset="0" a="{width}" b="0" c="0" d="0"/><roadMark sOffset="0" type="solid" color="white" width="0.15" laneChange="none"/></lane>')  # fmt: skip


def _two_way_road(split: float, near_width: float, far_width: float) -> str:
    """A straight 400 m two-way road heading east: lane -1 (eastbound) 3.5 m; lane 1 (westbound) ``near_width`` m
    wide up to x = ``split`` and ``far_width`` m beyond."""
    sections = "".join(
        f'<laneSection s="{s}"><left>{_lane(1, "driving", w)}</left>'
        '<center><lane id="0" type="none" level="false"/></center>'
        f'<right>{_lane(-1, "driving", 3.5)}{_lane(-2, "sidewalk", 2.0)}</right></laneSection>'
        for s, w in ((0, near_width), (split, far_width))
    )
    return (
        '<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="4" name="TwoWay"/>'
        '<road name="Road 1" length="400" id="1" junction="-1"><link/>'
        '<type s="0" type="town"><speed max="50" unit="km/h"/></type>'
        '<planView><geometry s="0" x="0" y="0" hdg="0" length="400"><line/></geometry></planView>'
        '<elevationProfile><elevation s="0" a="0" b="0" c="0" d="0"/></elevationProfile>'
        f'<lanes><laneOffset s="0" a="0" b="0" c="0" d="0"/>{sections}</lanes></road></OpenDRIVE>'
    )


@pytest.fixture(scope="module")
def two_way(tmp_path_factory):
    """Lane 1 is 3.0 m wide up to x = 120 and 4.0 m beyond."""
    path = tmp_path_factory.mktemp("roads") / "TwoWay.xodr"
    path.write_text(_two_way_road(120.0, 3.0, 4.0))
    return load_opendrive(path)


def _invading_turn(town, distance: float, offset: float = 0.25):
    y = 3.5 / 2.0  # lane -1's centre (CARLA y: OpenDRIVE's right is +y)
    lane = lane_walk(town.get_waypoint(Location(2.0, y, 0.0)), 390.0)
    dense = DenseRoute.from_pairs([(wp, RoadOption.LANEFOLLOW) for wp in lane], town)
    config = ScenarioConfig("InvadingTurn_1", "InvadingTurn", Transform(Location(20.0, y, 0.0), Rotation(yaw=0.0)),
                            {"distance": {"value": str(distance)}, "offset": {"value": str(offset)}})  # fmt: skip
    ctx = ScenarioContext(sim=None, map=town, route=dense, config=config,  # type: ignore[arg-type]
                          rng=np.random.default_rng(0), ego_id=EGO)  # fmt: skip
    return scenario_class("InvadingTurn")(ctx)


@pytest.mark.parametrize(("distance", "cones"), [(100.0, 10), (90.0, 9), (95.0, 10)])
def test_invading_turn_cones_as_lb20(two_way, distance, cones):
    # invading_turn.py _create_obstacle: next_wp = source.next(10)[0]; dist = 0; while dist < 0.5 * distance:
    # next_wp = next_wp.next(5)[0], a cone there, dist += 5. So ceil(distance / 10) cones, 15, 20, ... m from the
    # source: distance 100 -> dist 0..45, 10 cones (15..60 m); 90 -> 9 (15..55 m); 95 -> dist 0..45 (45 < 47.5),
    # 10. (Ours had 11, 10 and 10: `s <= 15 + distance / 2`.) The source is on lane 1 abreast of the trigger point
    # + distance + 30: x = 20 + distance + 30; lane 1 runs west, so cone k stands at x = source - 15 - 5 k; each
    # 0.8 x width / 2 right of lane 1's centre, toward the road's edge.
    scenario = _invading_turn(two_way, distance)
    source_x = 20.0 + distance + 30.0
    assert scenario.flow_waypoints[0].transform.location.x == pytest.approx(source_x, abs=0.01)
    transforms = scenario.cone_transforms()
    assert len(transforms) == cones
    for k, t in enumerate(transforms):
        assert t.location.x == pytest.approx(source_x - 15.0 - 5.0 * k, abs=0.01)
        # lane 1 (width w: 4.0 m from x = 120 on, 3.0 m before) has its centre at CARLA y = -w / 2 (left of the
        # reference line) and its right toward -y: the cone at -(w / 2 + 0.4 w) = -0.9 w
        width = 4.0 if t.location.x > 120.0 else 3.0
        assert t.location.y == pytest.approx(-0.9 * width, abs=0.01)


def test_invading_turn_offset_uses_the_sink_lane_width(two_way):
    # invading_turn.py _initialize_actors: _true_offset = -(offset + sink_wp.lane_width / 2 - 0.7), sink_wp =
    # trigger waypoint's left lane (lane 1 at x = 20: 3.0 m), not the source's (x = 150: 4.0 m):
    # -(0.25 + 1.5 - 0.7) = -1.05 (ours was -(0.25 + 2.0 - 0.7) = -1.55).
    scenario = _invading_turn(two_way, 100.0)
    assert scenario.flow_waypoints[0].lane_width == pytest.approx(4.0)
    assert scenario.lateral == pytest.approx(-1.05)
