"""Traffic-light groups: CARLA's cycle (green 10 s, yellow 3 s, all-red 2 s per pole), overrides, freezing."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from b2d_data.format.transform import BoundingBox, Location, Rotation, Transform
from b2d_data.sim.api import SimulatorError, TrafficLightState
from b2d_data.sim.builtin.traffic_lights import LightTiming, TrafficLightController, furniture_spec, union_box

G, Y, R = TrafficLightState.GREEN, TrafficLightState.YELLOW, TrafficLightState.RED
DT = 0.05


@dataclass
class _Wp:
    transform: Transform
    lane_width: float = 3.5


def _spec(signal_id: str, x: float, y: float, sequence: int, junction: int = 7):
    wp = _Wp(Transform(Location(x, y, 0.0), Rotation(yaw=0.0)))
    box = BoundingBox(Location(x, y, 1.0), Location(1.5, 0.875, 1.0), Rotation(yaw=0.0))
    actor = Transform(Location(x + 2.0, y + 4.0, 0.0), Rotation(yaw=90.0))
    return furniture_spec("traffic.traffic_light", signal_id, actor, [box], [wp], [wp], (0.25, 0.3, 0.6), 3.0,
                          group_key=junction, pole_key=(sequence, f"c{sequence}"))


def _controller(n_poles: int = 2, timing: LightTiming = LightTiming()):
    lights = [(100 + k, _spec(str(k), 10.0 * k, 0.0, k)) for k in range(n_poles)]
    return TrafficLightController(lights, timing)


def _run(ctrl, seconds: float) -> None:
    for _ in range(round(seconds / DT)):
        ctrl.advance(DT)


def test_one_pole_green_at_a_time_with_carla_timing():
    ctrl = _controller(3)
    assert [ctrl.state(i) for i in (100, 101, 102)] == [G, R, R]
    _run(ctrl, 9.95)
    assert ctrl.state(100) is G
    _run(ctrl, 0.05)  # t = 10 s
    assert ctrl.state(100) is Y and ctrl.state(101) is R
    _run(ctrl, 3.0)  # t = 13 s: all red for 2 s
    assert [ctrl.state(i) for i in (100, 101, 102)] == [R, R, R]
    _run(ctrl, 1.95)
    assert ctrl.state(101) is R
    _run(ctrl, 0.05)  # t = 15 s: the next pole
    assert [ctrl.state(i) for i in (100, 101, 102)] == [R, G, R]
    _run(ctrl, 30.0)  # two more poles: back to the first one at t = 45 s
    assert [ctrl.state(i) for i in (100, 101, 102)] == [G, R, R]
    infos = ctrl.infos()
    # pole 1 went yellow at 25 s and red at 28 s: red for 17 s now; pole 0 just turned green
    assert infos[100].elapsed_time == pytest.approx(0.0, abs=1e-6) and infos[101].elapsed_time == pytest.approx(17.0)


def test_override_with_freeze_holds_until_released():
    ctrl = _controller(2)
    ctrl.set_state(101, G, freeze=True)
    _run(ctrl, 40.0)
    assert ctrl.state(101) is G and ctrl.infos()[101].frozen
    ctrl.freeze_all(False)  # releases the frozen light; it rejoins at its group's next stage change
    _run(ctrl, 30.0)
    assert not ctrl.infos()[101].frozen


def test_override_without_freeze_lasts_until_the_next_stage_change():
    ctrl = _controller(2)
    ctrl.set_state(100, R, freeze=False)  # pole 0 is green: forced red until t = 10 s
    _run(ctrl, 5.0)
    assert ctrl.state(100) is R
    _run(ctrl, 5.0)
    assert ctrl.state(100) is Y


def test_freeze_all_stops_every_cycle():
    ctrl = _controller(2)
    _run(ctrl, 4.0)
    ctrl.freeze_all(True)
    _run(ctrl, 60.0)
    assert ctrl.state(100) is G and ctrl.infos()[100].frozen
    ctrl.freeze_all(False)
    _run(ctrl, 6.0)
    assert ctrl.state(100) is Y


def test_unknown_light_is_an_error():
    with pytest.raises(SimulatorError, match="42"):
        _controller().set_state(42, G)


def test_seeded_phases_differ_between_seeds_but_repeat():
    lights = [(100 + k, _spec(str(k), 10.0 * k, 0.0, k, junction=k // 2)) for k in range(8)]

    def states(seed):
        ctrl = TrafficLightController(lights, LightTiming(), rng=np.random.default_rng(seed))
        return [(ctrl.state(i), round(ctrl.infos()[i].elapsed_time, 6)) for i in range(100, 108)]

    assert states(1) == states(1)
    assert states(1) != states(2)


def test_trigger_volume_in_the_actor_frame():
    spec = _spec("9", 0.0, 0.0, 0)
    # actor at (2, 4) with yaw 90°; the world box centre (0, 0, 1) is d = (−2, −4) away, i.e. in the actor frame
    # x' = dx cos90 + dy sin90 = −4, y' = −dx sin90 + dy cos90 = 2; the box turns by 0 − 90 = −90°.
    tv = spec.trigger_volume
    assert (tv.location.x, tv.location.y, tv.location.z) == pytest.approx((-4.0, 2.0, 1.0))
    assert tv.rotation.yaw == pytest.approx(-90.0)
    assert (tv.extent.x, tv.extent.y) == (1.5, 0.875)
    # the head box is world-placed 3 m above the lane, facing the traffic (lane yaw + 180°)
    assert spec.level_bbox.location.z == pytest.approx(3.0) and abs(spec.level_bbox.rotation.yaw) == 180.0


def test_union_of_two_lane_boxes():
    a = BoundingBox(Location(0, 0, 1), Location(1.5, 1.0, 1.0), Rotation(yaw=0))
    b = BoundingBox(Location(0, 3.5, 1), Location(1.5, 1.0, 1.0), Rotation(yaw=0))
    u = union_box([a, b])
    assert (u.location.x, u.location.y) == pytest.approx((0.0, 1.75))
    assert (u.extent.x, u.extent.y, u.extent.z) == pytest.approx((1.5, 2.75, 1.0))
    assert math.isclose(u.rotation.yaw, 0.0)
