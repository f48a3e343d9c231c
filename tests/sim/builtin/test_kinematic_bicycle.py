"""The vehicle model, worked out by hand from the §1.6 bicycle and the longitudinal law."""

from __future__ import annotations

import math

import numpy as np
import pytest

from b2d_data.expert.config import ExpertConfig
from b2d_data.expert.kinematic_bicycle import ego_next_speed, forecast_ego
from b2d_data.format.transform import Location, Rotation, Transform, Vector3D
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorSpec, VehicleControl
from b2d_data.sim.builtin import kinematic_bicycle as kb

DT = 0.05


def _one(speed: float = 0.0, **controls: float) -> kb.VehicleArrays:
    state = np.zeros((1, len(kb.STATE_COLUMNS)))
    state[0, kb.STATE_COLUMNS.index("speed")] = speed
    for name, value in controls.items():
        state[0, kb.STATE_COLUMNS.index(name)] = value
    params = kb.param_row(blueprints.CAR_DYNAMICS, blueprints.DEFAULT_GEOMETRY)[None, :]
    return kb.VehicleArrays.from_rows(state, params)


def test_straight_line_at_constant_speed_travels_v_t():
    x, y, yaw = np.zeros(1), np.zeros(1), np.zeros(1)
    for _ in range(40):  # 2 s at 10 m/s
        x, y, yaw = kb.bicycle_kinematics(x, y, yaw, np.array([10.0]), np.zeros(1), np.array([1.41783]), DT)
    assert x[0] == pytest.approx(20.0) and y[0] == 0.0 and yaw[0] == 0.0


def test_steady_steer_drives_the_predicted_circle():
    g = blueprints.DEFAULT_GEOMETRY
    beta = g.slip_angle(0.4)
    radius = g.turn_radius(0.4)  # l_r / sin β ≈ 9.47 m
    v = 5.0
    x, y, yaw = np.zeros(1), np.zeros(1), np.zeros(1)
    pts = []
    for _ in range(400):
        x, y, yaw = kb.bicycle_kinematics(x, y, yaw, np.array([v]), np.array([beta]), np.array([g.rear_length]), DT)
        pts.append((x[0], y[0]))
    pts = np.array(pts)
    # fit a circle: x² + y² + D x + E y + F = 0 (least squares)
    a = np.column_stack([pts[:, 0], pts[:, 1], np.ones(len(pts))])
    rhs = -(pts[:, 0] ** 2 + pts[:, 1] ** 2)
    d, e, f = np.linalg.lstsq(a, rhs, rcond=None)[0]
    fitted = math.sqrt(d * d / 4 + e * e / 4 - f)
    # Euler chords of length v·dt turning by ω·dt lie on a circle (v·dt/2)/sin(ω·dt/2): 0.05 % above R here
    assert fitted == pytest.approx(radius, rel=2e-3)
    # positive steer turns clockwise seen from above: toward +y (right) in CARLA's frame
    assert pts[10, 1] > 0.0


def test_full_brake_from_10_stops_within_the_decel_distance():
    v = _one(speed=10.0, brake=1.0)
    travelled, ticks = 0.0, 0
    while v.speed[0] > 0.0:
        x0 = v.x[0]
        kb.step(v, DT)
        travelled += v.x[0] - x0
        ticks += 1
    # decel ≥ 8 (brake) + 0.25 (rolling): v²/(2a) + v·dt/2 (positions use the speed before each update)
    assert travelled <= 10.0**2 / (2 * 8.25) + 10.0 * DT / 2 + 1e-9
    assert travelled > 10.0**2 / (2 * 8.5)
    assert ticks == math.ceil(10.0 / (8.25 * DT)) or ticks == math.ceil(10.0 / (8.25 * DT)) - 1
    assert v.speed[0] == 0.0  # and it does not roll backwards


def test_full_throttle_from_rest_accelerates_at_the_model_rate():
    v = _one(throttle=1.0)
    kb.step(v, DT)
    # drive 3.8 m/s² at 0 m/s minus rolling 0.25 m/s²
    assert v.speed[0] == pytest.approx((3.8 - 0.25) * DT)


def test_coasting_slows_down_and_stops():
    v = _one(speed=5.0)
    for _ in range(20 * 20):
        kb.step(v, DT)
    assert v.speed[0] == 0.0


def test_reverse_and_hand_brake():
    v = _one(throttle=1.0, reverse=1.0)
    for _ in range(20):
        kb.step(v, DT)
    assert v.speed[0] < -2.0 and v.x[0] < 0.0
    v = _one(speed=10.0, hand_brake=1.0)
    kb.step(v, DT)
    assert v.speed[0] == pytest.approx(10.0 - (6.0 + 0.25 + 4e-4 * 100.0) * DT)


def test_steer_rate_limit():
    v = _one(speed=5.0, steer_cmd=1.0)
    kb.step(v, DT)
    assert v.steer[0] == pytest.approx(blueprints.CAR_DYNAMICS.max_steer_rate * DT)


def test_inverse_longitudinal_model():
    d = blueprints.CAR_DYNAMICS
    throttle, brake = kb.accel_for(d, 10.0, 1.0)
    assert brake == 0.0
    assert throttle * (d.max_accel - d.accel_falloff * 10.0) - d.rolling - d.drag * 100.0 == pytest.approx(1.0)
    throttle, brake = kb.accel_for(d, 10.0, -4.0)
    assert throttle == 0.0 and brake * d.max_brake + d.rolling + d.drag * 100.0 == pytest.approx(4.0)


# ------------------------------------------------------------------ the ego's Lincoln: PDM-Lite's CARLA polynomials
# Expected values are worked out from the polynomials of ExpertConfig (§1.6), v in km/h, one 0.05 s step:
#   throttle: next = c0·v + c1·v² + c2·t + c3·t² + c4·v·t + c5·v·t² + c6·v²·t + c7·v²·t²
#   brake:    next = Σ b_k·v^k, k = 1…7
# The law turns each into the acceleration (next/3.6 − v)/0.05, so a 0.05 s tick gives the polynomial's speed up to
# float rounding (1e-9 below is that rounding with margin, not a fit tolerance).

EGO = blueprints.EGO_DYNAMICS
ROLLING, DRAG = np.array([EGO.rolling]), np.array([EGO.drag])


def _ego(speed: float = 0.0, **controls: float) -> kb.VehicleArrays:
    state = np.zeros((1, len(kb.STATE_COLUMNS)))
    state[0, kb.STATE_COLUMNS.index("speed")] = speed
    for name, value in controls.items():
        state[0, kb.STATE_COLUMNS.index(name)] = value
    return kb.VehicleArrays.from_rows(state, kb.param_row(EGO, blueprints.DEFAULT_GEOMETRY)[None, :])


def _accel(speed: float, throttle: float = 0.0, brake: float = 0.0) -> float:
    return float(kb.lincoln_accel(np.array([speed]), np.array([throttle]), np.array([brake]), ROLLING, DRAG)[0])


@pytest.mark.parametrize(
    ("speed", "controls", "next_speed"),
    [
        # full throttle from rest: c2 + c3 = −0.380192912 + 1.74950069 = 1.369307778 km/h = 0.380363272 m/s
        (0.0, {"throttle": 1.0}, 0.380363272),
        # throttle 0.5 from rest: −0.190096456 + 0.437375173 = 0.247278717 km/h = 0.068688532 m/s (1.37 m/s², where
        # the linear law gave 3.6)
        (0.0, {"throttle": 0.5}, 0.068688532),
        # throttle 0.75 from rest: −0.285144684 + 0.984094138 = 0.698949454 km/h = 0.194152626 m/s
        (0.0, {"throttle": 0.75}, 0.194152626),
        # throttle 0.3 at 18 km/h: 17.349714 + 0.141762 − 0.114058 + 0.157455 + 0.495065 − 0.114285 − 0.103028
        # + 0.019568 = 17.832194 km/h = 4.953387 m/s: CARLA's Lincoln slows down (−0.93 m/s²)
        (5.0, {"throttle": 0.3}, 4.953387117),
        # full brake at 36 km/h: 0.335416 + 106.397379 − 132.424857 + 85.087243 − 29.650026 + 5.320476 − 0.385067
        # = 34.680563 km/h = 9.633490 m/s, whatever the throttle (PDM-Lite's forecast drops it too)
        (10.0, {"brake": 1.0}, 9.633489635),
        (10.0, {"brake": 1.0, "throttle": 1.0}, 9.633489635),
    ],
)
def test_ego_single_steps_follow_the_polynomials(speed, controls, next_speed):
    v = _ego(speed, **controls)
    kb.step(v, DT)
    assert v.speed[0] == pytest.approx(next_speed, abs=1e-9)
    assert v.x[0] == pytest.approx(speed * DT, abs=1e-12)  # positions use the speed before the update


def test_ego_coasting_is_at_least_throttle_03s_engine_braking():
    # throttle 0 at 36 km/h: the polynomial at throttle 0.3 gives 35.737594 km/h (−1.457811 m/s²), more than rolling +
    # drag (0.25 + 4e-4·100 = 0.29 m/s²); a car that slows that much at throttle 0.3 slows at least that much at 0
    assert _accel(10.0) == pytest.approx((35.737594009 / 3.6 - 10.0) / DT, abs=1e-6)
    # at 90 km/h the polynomial at 0.3 would not slow the car (+0.8 m/s², outside its range): rolling + drag, 0.5 m/s²
    assert _accel(25.0) == pytest.approx(-(0.25 + 4e-4 * 625.0))
    # at 0.5 m/s throttle 0.3 creeps forward (+0.0946 m/s²): coasting is rolling + drag, 0.2501 m/s²
    assert _accel(0.5) == pytest.approx(-0.2501)


def test_ego_small_throttles_interpolate_to_the_polynomial_at_03():
    # 0.15 at 0.5 m/s: halfway between coasting (−0.2501) and throttle 0.3 (f(1.8, 0.3) = 1.817030 km/h → +0.094609)
    assert _accel(0.5, 0.15) == pytest.approx(-0.2501 + 0.5 * (0.094609 + 0.2501), abs=1e-6)
    # where throttle 0.3 already slows more than rolling + drag (1–22 m/s) every throttle below 0.3 acts like 0.3
    assert _accel(10.0, 0.1) == pytest.approx(_accel(10.0, 0.3))
    # continuous at the threshold and never decreasing with throttle, from 0 to 50 m/s
    speeds = np.linspace(0.0, 50.0, 501)
    ones = np.ones_like(speeds)
    grid = np.array([kb.lincoln_accel(speeds, t * ones, 0 * ones, EGO.rolling * ones, EGO.drag * ones)
                     for t in np.linspace(0.0, 1.0, 201)])
    assert np.diff(grid, axis=0).min() >= -1e-12
    below = kb.lincoln_accel(speeds, (0.3 - 1e-9) * ones, 0 * ones, EGO.rolling * ones, EGO.drag * ones)
    at = kb.lincoln_accel(speeds, 0.3 * ones, 0 * ones, EGO.rolling * ones, EGO.drag * ones)
    assert np.abs(at - below).max() < 1e-6


def test_ego_partial_brake_blends_and_hand_brake_adds():
    # brake 0.5 at 10 m/s: 0.5 · (coasting −1.457811) + 0.5 · (full brake −7.330207) = −4.394009 m/s²
    assert _accel(10.0, brake=0.5) == pytest.approx(0.5 * -1.457811 + 0.5 * -7.330207, abs=1e-5)
    v = _ego(10.0, hand_brake=1.0)
    kb.step(v, DT)
    assert v.speed[0] == pytest.approx(10.0 + (-1.4578111 - 6.0) * DT, abs=1e-7)


def test_ego_reverse_keeps_the_linear_law():
    # drive backwards 7.711 m/s² at 0 m/s, minus rolling 0.25 m/s² toward 0: −7.461 · 0.05 = −0.37305 m/s
    v = _ego(throttle=1.0, reverse=1.0)
    kb.step(v, DT)
    assert v.speed[0] == pytest.approx(-0.37305)


def test_ego_above_the_polynomials_speed_range():
    # Full throttle at 80 km/h: f(80, 1) = 80.481137 km/h → 2.672986 m/s²; less coasting there (0.25 + 4e-4·22.22²
    # = 0.447531) the polynomial's driving part is 3.120517 m/s². At 30 m/s, at constant power: 3.120517 · 22.222/30
    # − (0.25 + 0.36) = 1.701494 m/s².
    assert _accel(30.0, 1.0) == pytest.approx(1.701494, abs=1e-6)
    assert _accel(80.0 / 3.6 - 1e-9, 1.0) == pytest.approx(_accel(80.0 / 3.6 + 1e-9, 1.0), abs=1e-6)
    # the brake polynomial is held at its 108 km/h value: g(108) = 106.706319 km/h → −7.187119 m/s²
    assert _accel(35.0, brake=1.0) == pytest.approx(-7.187119, abs=1e-6)


@pytest.mark.parametrize(
    ("speed", "accel", "controls"),
    [
        (0.0, 0.380363272 / DT, (1.0, 0.0)),
        (0.0, 0.068688532 / DT, (0.5, 0.0)),
        (5.0, (4.953387117 - 5.0) / DT, (0.3, 0.0)),
        (10.0, 0.5 * -1.457811 + 0.5 * -7.330207, (0.0, 0.5)),
        (10.0, -20.0, (0.0, 1.0)),
        (10.0, 9.0, (1.0, 0.0)),
        (0.5, -0.2501 + 0.5 * (0.094609 + 0.2501), (0.15, 0.0)),
    ],
)
def test_ego_inverse_model_hand_points(speed, accel, controls):
    assert kb.accel_for(EGO, speed, accel) == pytest.approx(controls, abs=1e-5)


def test_ego_inverse_model_round_trip():
    # background traffic also drives mkz_2020s through accel_for: whatever acceleration the law can give, the inverse
    # must find controls that give it (0–45 m/s, the polynomial's range and beyond)
    rng = np.random.default_rng(0)
    for _ in range(2000):
        speed, throttle = rng.uniform(0.0, 45.0), rng.uniform(0.0, 1.0)
        brake = rng.uniform(0.0, 1.0) if rng.uniform() < 0.3 else 0.0
        wanted = _accel(speed, 0.0 if brake else throttle, brake)
        got = _accel(speed, *kb.accel_for(EGO, speed, wanted))
        assert got == pytest.approx(wanted, abs=1e-9)


def test_inverse_models_of_many_vehicles_are_each_alone_to_the_bit():
    # background traffic solves its vehicles' pedals together: Lincolns (polynomials evaluated for all at once) among
    # linear-law cars, speeds from reversing to above the polynomial's range, every branch of the inverse
    rng = np.random.default_rng(4)
    car = blueprints.CAR_DYNAMICS
    dynamics = [EGO if rng.uniform() < 0.6 else car for _ in range(300)]
    speeds = rng.uniform(-2.0, 40.0, 300)
    accels = rng.uniform(-12.0, 6.0, 300)
    # and the narrow band between coasting and the throttle threshold (throttle 0.15 at 0.5 m/s, see above)
    dynamics.append(EGO)
    speeds, accels = np.append(speeds, 0.5), np.append(accels, -0.2501 + 0.5 * (0.094609 + 0.2501))
    many = kb.accel_for_many(dynamics, speeds.tolist(), accels.tolist())
    assert many == [kb.accel_for(d, float(v), float(a)) for d, v, a in zip(dynamics, speeds, accels)]
    # the Lincolns hit every branch: full throttle, the polynomial, below the threshold, braking, held at a stand
    kinds = {(t == 1.0, 0.3 <= t < 1.0, 0.0 < t < 0.3, b > 0.0) for d, (t, b) in zip(dynamics, many) if d is EGO}
    assert {(True, False, False, False), (False, True, False, False), (False, False, True, False),
            (False, False, False, True)} <= kinds
    assert kb.accel_for_many([], [], []) == []


# ------------------------------------------------------------- step responses of the ego in the BuiltinSimulator
# The hero Lincoln on the flat stand-in town (tests/sim/conftest.py) against PDM-Lite's ego model (the expert's
# ``ego_next_speed`` iterated with x += v·dt, i.e. the CARLA fit); the figures in the comments are that iteration's.
# Tolerance 1e-6 m/s and m: the world only adds float rounding to the law (its pose goes through degrees).

HERO = ActorSpec("vehicle.lincoln.mkz_2020", role_name="hero")
PDM = ExpertConfig()


def _world_run(world, speed: float, control: VehicleControl, ticks: int) -> tuple[list[float], list[float]]:
    """(speeds, distances) of the hero over ``ticks`` ticks of ``control`` from ``speed`` (m/s) on a straight line."""
    hero = world.spawn_actor(HERO, Transform(Location(0.0, 0.0, 0.0), Rotation()))
    x0 = 0.0
    if speed > 0.0:
        world.set_target_velocity(hero, Vector3D(speed, 0.0, 0.0))  # one tick at exactly this speed
        x0 = world.tick().actors[hero].location.x
    world.apply_control(hero, control)
    speeds, distances = [], []
    for _ in range(ticks):
        state = world.tick().actors[hero]
        speeds.append(state.forward_speed())
        distances.append(state.location.x - x0)
    return speeds, distances


def _pdm_run(speed: float, throttle: float, brake: bool, ticks: int) -> tuple[list[float], list[float]]:
    x, speeds, distances = 0.0, [], []
    for _ in range(ticks):
        x += speed * DT
        speed = ego_next_speed(PDM, speed, throttle, brake)
        speeds.append(speed)
        distances.append(x)
    return speeds, distances


@pytest.mark.parametrize(
    ("speed", "control", "ticks", "final_speed", "final_distance"),
    [
        # full throttle from rest for 3 s: 15.945 m/s after 26.376 m (the linear law: 15.896 m/s, 26.395 m)
        (0.0, VehicleControl(throttle=1.0), 60, 15.945083, 26.376446),
        # throttle 0.5 from rest for 3 s: 3.349 m/s, 5.290 m (linear law: 9.07 m/s)
        (0.0, VehicleControl(throttle=0.5), 60, 3.348718, 5.290099),
        # throttle 0.75 from rest for 5 s: 14.443 m/s, 39.309 m (linear law: 18.04 m/s)
        (0.0, VehicleControl(throttle=0.75), 100, 14.443255, 39.308696),
        # throttle 0.3 at 5 m/s for 2 s slows to 3.434 m/s (linear law: speeds up at 1.7 m/s² to 8.14 m/s)
        (5.0, VehicleControl(throttle=0.3), 40, 3.434254, 8.373697),
    ],
)
def test_ego_step_responses_in_the_world(flat_world, speed, control, ticks, final_speed, final_distance):
    speeds, distances = _world_run(flat_world, speed, control, ticks)
    expected_speeds, expected_distances = _pdm_run(speed, control.throttle, False, ticks)
    assert np.allclose(speeds, expected_speeds, atol=1e-6, rtol=0.0)
    assert np.allclose(distances, expected_distances, atol=1e-6, rtol=0.0)
    assert (speeds[-1], distances[-1]) == pytest.approx((final_speed, final_distance), abs=1e-5)


def test_ego_full_brake_from_10_in_the_world(flat_world):
    speeds, distances = _world_run(flat_world, 10.0, VehicleControl(brake=1.0), 30)
    expected_speeds, expected_distances = _pdm_run(10.0, 0.0, True, 30)
    assert np.allclose(speeds, expected_speeds, atol=1e-6, rtol=0.0)
    assert np.allclose(distances, expected_distances, atol=1e-6, rtol=0.0)
    # 10 → 9.633 → 9.253 → … → 0.616 → 0.110 → 0.0045 m/s: below 1 cm/s after 16 ticks (0.8 s), 4.697 m on
    # (7.3 m/s² at first, up to 22.7 m/s² near 3 m/s; the linear law took 1.25 s and 6.30 m at 8.25–8.29 m/s²)
    stopped = next(k for k, v in enumerate(speeds) if v < 0.01) + 1
    assert stopped == 16 and speeds[14] > 0.1
    assert distances[-1] == pytest.approx(4.696776, abs=1e-5)
    assert min(speeds) >= 0.0  # never backwards


def test_ego_coasting_in_the_world(flat_world):
    # no polynomial for throttle 0 (PDM-Lite's forecast keeps the speed); the law brakes at least like throttle 0.3,
    # which between 1 and 22 m/s is throttle 0.3's polynomial itself: from 10 m/s, 8.578 m/s after 1 s and 4.188 m/s
    # after 5 s, 34.155 m on (the old linear law: 8.58 m/s after 5 s)
    speeds, distances = _world_run(flat_world, 10.0, VehicleControl(), 100)
    expected_speeds, expected_distances = _pdm_run(10.0, 0.3, False, 100)
    assert np.allclose(speeds, expected_speeds, atol=1e-6, rtol=0.0)
    assert np.allclose(distances, expected_distances, atol=1e-6, rtol=0.0)
    assert (speeds[19], speeds[-1], distances[-1]) == pytest.approx((8.577928, 4.187542, 34.154886), abs=1e-5)


def test_ego_steer_step_against_the_expert_forecast(flat_world):
    # Steer 0.5 at 5 m/s for 2 s (throttle 0.5, so that both sides follow the same speed polynomial). The geometry is
    # the fitted bicycle of §1.6 on both sides (the simulator's constants are its 5-digit roundings: ≤ 0.1 mm here);
    # the simulator also limits the steer rate to 5 per second, so its first tick steers 0.25, not 0.5.
    hero = flat_world.spawn_actor(HERO, Transform(Location(0.0, 0.0, 0.0), Rotation()))
    flat_world.set_target_velocity(hero, Vector3D(5.0, 0.0, 0.0))
    start = flat_world.tick().actors[hero].location
    flat_world.apply_control(hero, VehicleControl(throttle=0.5, steer=0.5))
    poses = []
    for _ in range(40):
        state = flat_world.tick().actors[hero]
        poses.append((state.location.x - start.x, state.location.y - start.y,
                      math.radians(state.transform.rotation.yaw), state.speed()))  # |v|: it moves along ψ + β

    def forecast(steers: list[float]) -> list[tuple[float, float, float, float]]:
        x = y = yaw = 0.0
        v, out = 5.0, []
        for steer in steers:
            x, y, yaw, v = forecast_ego(PDM, x, y, yaw, v, steer, 0.5, False)
            out.append((x, y, yaw, v))
        return out

    # with the steer the simulator applied (0.25, then 0.5) the forecast is where the ego is
    applied = forecast([0.25] + [0.5] * 39)
    assert max(math.hypot(p[0] - q[0], p[1] - q[1]) for p, q in zip(poses, applied)) < 1e-3
    assert max(abs(p[3] - q[3]) for p, q in zip(poses, applied)) < 1e-6
    # PDM-Lite's forecast steers 0.5 at once: the ego's heading stays behind by one tick's difference,
    # 5/1.41783 · (sin β(0.5) − sin β(0.25)) · 0.05 = 5/1.41783 · (0.195267 − 0.098223) · 0.05 = 0.017111 rad
    # (β(0.5) = 0.196530, β(0.25) = 0.098382), which after 2 s on the 7.3 m circle puts it 0.189 m from the forecast
    commanded = forecast([0.5] * 40)
    assert commanded[-1][2] - poses[-1][2] == pytest.approx(0.017111, abs=1e-4)
    gap = math.hypot(poses[-1][0] - commanded[-1][0], poses[-1][1] - commanded[-1][1])
    assert gap == pytest.approx(0.189, abs=0.002)
