"""The blueprint library: CARLA ids, kinds, extents, tags and seeded choices."""

from __future__ import annotations

import numpy as np
import pytest

from b2d_data.format.rig import EGO_HALF_EXTENT, EGO_TYPE_ID
from b2d_data.sim import blueprints
from b2d_data.sim.api import ActorKind, ActorSpec, SpawnError


def test_ego_uses_the_project_extent():
    ego = blueprints.find(EGO_TYPE_ID)
    assert ego.kind is ActorKind.VEHICLE and ego.base_type == "car"
    assert ego.extent == EGO_HALF_EXTENT == (2.451, 1.064, 0.755)
    # the box stands on the ground: its centre is one half height above the actor origin
    assert ego.bounding_box.location.z == pytest.approx(0.755)
    assert ego.semantic_tags == (14,)


@pytest.mark.parametrize(
    ("type_id", "base_type", "tags", "special"),
    [
        ("vehicle.dodge.charger_police_2020", "car", (14,), "emergency"),
        ("vehicle.ford.ambulance", "van", (15,), "emergency"),
        ("vehicle.carlamotors.firetruck", "truck", (15,), "emergency"),
        ("vehicle.mitsubishi.fusorosa", "bus", (16,), ""),
        ("vehicle.yamaha.yzf", "motorcycle", (18, 13), ""),
        ("vehicle.bh.crossbike", "bicycle", (19, 13), ""),
        ("vehicle.diamondback.century", "bicycle", (19, 13), ""),
        ("vehicle.gazelle.omafiets", "bicycle", (19, 13), ""),
    ],
)
def test_vehicle_classes(type_id, base_type, tags, special):
    bp = blueprints.find(type_id)
    assert (bp.base_type, bp.semantic_tags, bp.special_type) == (base_type, tags, special)
    assert bp.dynamics is not None and bp.geometry == blueprints.DEFAULT_GEOMETRY


def test_bicycles_have_two_wheels_and_slow_dynamics():
    bike = blueprints.find("vehicle.gazelle.omafiets")
    assert bike.number_of_wheels == 2
    assert bike.default_attributes()["base_type"] == "bicycle"
    assert bike.dynamics.max_accel < blueprints.CAR_DYNAMICS.max_accel


def test_walkers_carry_gender_and_age():
    adult = blueprints.find("walker.pedestrian.0001")
    child = blueprints.find("walker.pedestrian.0010")
    assert adult.kind is ActorKind.WALKER and adult.semantic_tags == (12,)
    assert adult.attributes["age"] == "adult" and child.attributes["age"] == "child"
    assert adult.attributes["gender"] in ("female", "male")
    assert child.extent[2] < adult.extent[2]
    assert len(blueprints.filter_ids("walker.pedestrian.*")) == 51


def test_props():
    cone = blueprints.find("static.prop.constructioncone")
    debris = blueprints.find("static.prop.dirtdebris01")
    assert cone.kind is ActorKind.PROP and cone.collides and cone.semantic_tags == (20,)
    assert not debris.collides  # flat debris: cars drive over it
    for name in ("trafficcone01", "warningconstruction", "warningaccident", "trafficwarning", "dirtdebris03",
                 "advertisement", "container", "streetbarrier"):
        assert blueprints.find(f"static.prop.{name}").kind is ActorKind.PROP


def test_parked_mesh_scales_its_box():
    path = next(iter(blueprints.PARKED_VEHICLE_MESHES))
    at_09 = blueprints.resolve(ActorSpec("static.prop.mesh", attributes={"mesh_path": path, "scale": "0.9"}))
    at_10 = blueprints.resolve(ActorSpec("static.prop.mesh", attributes={"mesh_path": path, "scale": "1.0"}))
    assert at_10.extent[0] == pytest.approx(at_09.extent[0] / 0.9)
    assert at_09.semantic_tags == (14,)
    with pytest.raises(SpawnError, match="unknown mesh_path"):
        blueprints.resolve(ActorSpec("static.prop.mesh", attributes={"mesh_path": "/Game/Nope"}))


def test_unknown_id_lists_close_matches():
    with pytest.raises(SpawnError) as err:
        blueprints.find("vehicle.lincoln.mkz2020")
    assert "vehicle.lincoln.mkz_2020" in str(err.value)


def test_background_cars_follow_lb2_filter():
    ids = blueprints.background_car_ids()
    assert ids and EGO_TYPE_ID in ids
    for type_id in ids:
        bp = blueprints.find(type_id)
        assert bp.base_type == "car" and bp.has_lights and bp.special_type == ""


def test_random_choices_are_seeded():
    a = [blueprints.random_background_car(np.random.default_rng(7)) for _ in range(3)]
    b = [blueprints.random_background_car(np.random.default_rng(7)) for _ in range(3)]
    assert a == b and a[0].role_name == "background"
    picks = {blueprints.random_background_car(np.random.default_rng(s)).type_id for s in range(40)}
    assert len(picks) > 1


def test_geometry_matches_expert_model():
    g = blueprints.DEFAULT_GEOMETRY
    # §1.6: wheel = 0.36848·steer; β = atan(l_r/(l_f+l_r)·tan(wheel)); radius of the reference point = l_r/sin β
    beta = np.arctan(1.41783 / (1.41783 - 0.09077) * np.tan(0.36848 * 0.5))
    assert g.slip_angle(0.5) == pytest.approx(beta)
    assert g.turn_radius(0.5) == pytest.approx(1.41783 / np.sin(beta))
    assert g.steer_for_curvature(1.0 / g.turn_radius(0.5)) == pytest.approx(0.5)


def _full_throttle(dynamics: blueprints.LongitudinalModel, speed: float, ticks: int) -> tuple[float, float]:
    """(distance, speed) after ``ticks`` steps of 0.05 s at full throttle on a straight line."""
    from b2d_data.sim.builtin import kinematic_bicycle as kb

    state = np.zeros((1, len(kb.STATE_COLUMNS)))
    state[0, kb.STATE_COLUMNS.index("speed")] = speed
    state[0, kb.STATE_COLUMNS.index("throttle")] = 1.0
    arr = kb.VehicleArrays.from_rows(state, kb.param_row(dynamics, blueprints.DEFAULT_GEOMETRY)[None, :])
    for _ in range(ticks):
        kb.step(arr, 0.05)
    return float(arr.x[0]), float(arr.speed[0])


def test_only_the_ego_lincoln_follows_the_carla_fit():
    # The ego's blueprint (also drawn by background traffic) follows PDM-Lite's CARLA Lincoln polynomials; every
    # other blueprint keeps the linear law that PDM-Lite's constant-acceleration forecast of other cars assumes.
    assert blueprints.find(EGO_TYPE_ID).dynamics is blueprints.EGO_DYNAMICS
    assert blueprints.EGO_DYNAMICS.law is blueprints.LongitudinalLaw.CARLA_LINCOLN
    assert blueprints.find("vehicle.lincoln.mkz_2017").dynamics is blueprints.CAR_DYNAMICS
    others = {bp.dynamics.law for t, bp in blueprints.BLUEPRINTS.items() if bp.dynamics is not None and t != EGO_TYPE_ID}
    assert others == {blueprints.LongitudinalLaw.LINEAR}


def test_the_simulator_uses_pdm_lites_lincoln_polynomials():
    # The simulator keeps its own copy of the coefficients (sim must not import the expert): they must be PDM-Lite's.
    from b2d_data.expert.config import ExpertConfig
    from b2d_data.sim.builtin import kinematic_bicycle as kb

    config = ExpertConfig()
    assert kb.LINCOLN_THROTTLE_POLY == config.ego_throttle_poly
    assert kb.LINCOLN_BRAKE_POLY == config.ego_brake_poly
    assert kb.LINCOLN_THROTTLE_THRESHOLD == config.ego_throttle_threshold
    assert kb.LINCOLN_POLY_DT == config.dt


def test_ego_forecast_from_standstill_matches_the_simulated_ego():
    # The forecast a standing ego makes before crossing a junction: 40 steps at full throttle. Summing PDM-Lite's
    # polynomial step by step (1.3693 km/h in the first step, ≈ 91.3·(1 − 0.985^k) km/h after k) gives 12.530 m at
    # 11.813 m/s after 2 s; the simulated ego now follows the same polynomial, so it is there to the float rounding.
    # (The linear law it had before drove 12.535 m; the generic car's 6.6 m.)
    from b2d_data.expert.config import ExpertConfig
    from b2d_data.expert.kinematic_bicycle import forecast_ego

    config = ExpertConfig()
    x = v = 0.0
    for _ in range(40):
        x, _, _, v = forecast_ego(config, x, 0.0, 0.0, v, 0.0, 1.0, False)
    assert (x, v) == pytest.approx((12.530, 11.813), abs=1e-3)
    distance, speed = _full_throttle(blueprints.EGO_DYNAMICS, 0.0, 40)
    assert distance == pytest.approx(x, abs=1e-9)
    assert speed == pytest.approx(v, abs=1e-9)
