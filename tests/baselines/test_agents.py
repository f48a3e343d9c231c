"""Each baseline agent's sensors() and run_step() on synthetic sensor data, with the evaluator's stand-in modules."""

from __future__ import annotations

import importlib.util
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
import torch

from b2d_data.closed_loop import SHIM_DIR
from b2d_data.format.transform import Location
from b2d_data.maps.geolocation import GeoReference

from baselines.agent_base import geo_reference, parse_config
from baselines.models import ADMLP, TCPConfig, TCPSmall

AGENTS = Path(__file__).resolve().parents[2] / "baselines" / "agents"
_SHIM_PACKAGES = ("carla", "leaderboard", "srunner", "agents")
#: A geo reference away from (0, 0) so that the agents really solve for it.
GEO = GeoReference(49.0, 8.0)


def _purge() -> None:
    for name in list(sys.modules):
        if name.split(".")[0] in _SHIM_PACKAGES:
            del sys.modules[name]


@pytest.fixture
def shim() -> Iterator[ModuleType]:
    """The evaluator's ``carla`` / ``leaderboard`` stand-ins importable (no route running), removed afterwards."""
    _purge()
    sys.path.insert(0, str(SHIM_DIR))
    try:
        yield importlib.import_module("carla")
    finally:
        sys.path.remove(str(SHIM_DIR))
        _purge()


def _agent(file: str, config: str, carla: ModuleType):
    spec = importlib.util.spec_from_file_location(f"_baseline_{file}", AGENTS / file)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    cls = getattr(module, module.get_entry_point())
    agent = cls.__new__(cls)  # the base constructor looks the ego up in a running world: not needed here
    from agents.navigation.local_planner import RoadOption

    # A straight route east along y = 0, 1 m apart, as the evaluator hands it over (GPS and world poses).
    world = [(carla.Transform(carla.Location(x=float(x), y=0.0, z=0.0)), RoadOption.LANEFOLLOW) for x in range(101)]
    gps = []
    for transform, option in world:
        g = GEO.transform(Location(transform.location.x, transform.location.y, 0.0))
        gps.append(({"lat": g.latitude, "lon": g.longitude, "z": 0.0}, option))
    agent.set_global_plan(gps, world)
    agent.setup(config)
    return agent


def _input(x: float, speed: float, width: int = 64, height: int = 36) -> dict:
    g = GEO.transform(Location(x, 0.0, 0.0))
    compass = math.pi / 2.0  # CARLA yaw 0 (east) + 90°
    image = np.full((height, width, 4), 128, np.uint8)
    return {
        "GPS": (1, np.array([g.latitude, g.longitude, 0.0])),
        "IMU": (1, np.array([0.0, 0.0, 9.81, 0.0, 0.0, 0.0, compass])),
        "SPEED": (1, {"speed": speed}),
        "CAM_FRONT": (1, image),
    }


def _valid(control) -> None:
    assert 0.0 <= control.throttle <= 1.0 and 0.0 <= control.brake <= 1.0 and -1.0 <= control.steer <= 1.0
    assert all(math.isfinite(v) for v in (control.throttle, control.steer, control.brake))


def test_geo_reference_round_trip() -> None:
    g = GEO.transform(Location(120.0, -35.0, 0.0))
    ref = geo_reference(g.latitude, g.longitude, 120.0, -35.0)
    assert (ref.lat_0, ref.lon_0) == pytest.approx((49.0, 8.0), abs=1e-9)


def test_parse_config() -> None:
    assert parse_config("runs/a/last.pt+RouteScenario_1_rep0_x") == {"ckpt": "runs/a/last.pt"}
    assert parse_config("ckpt=a.pt,planner=only_ctrl+save") == {"ckpt": "a.pt", "planner": "only_ctrl"}
    assert parse_config("") == {}


def test_route_follower_drives_the_route(shim: ModuleType) -> None:
    agent = _agent("route_follower_agent.py", "speed=6+save", shim)
    assert [s["id"] for s in agent.sensors()] == ["GPS", "IMU", "SPEED"]
    control = agent.run_step(_input(10.0, 0.0), 0.0)
    _valid(control)
    # At rest on a straight route: full throttle request (0.75 cap), no brake, straight wheel.
    assert control.throttle == pytest.approx(0.75) and control.brake == 0.0 and abs(control.steer) < 1e-3
    # Far above the set speed: brake (7.0 / 6.0 > 1.1).
    fast = agent.run_step(_input(10.5, 7.0), 0.05)
    assert fast.brake == 1.0 and fast.throttle == 0.0


def test_admlp_agent_step(shim: ModuleType, tmp_path: Path) -> None:
    torch.manual_seed(0)
    net = ADMLP()
    ckpt = tmp_path / "admlp.pt"
    torch.save({"kind": "admlp", "model_config": net.config.to_dict(), "model": net.state_dict()}, ckpt)
    agent = _agent("admlp_agent.py", f"ckpt={ckpt},device=cpu+save", shim)
    assert {s["type"] for s in agent.sensors()} == {"sensor.other.gnss", "sensor.other.imu", "sensor.speedometer"}
    for k in range(3):
        control = agent.run_step(_input(10.0 + 0.25 * k, 5.0), 0.05 * k)
        _valid(control)
    assert agent.last_waypoints.shape == (6, 3)


def test_tcp_agent_step(shim: ModuleType, tmp_path: Path) -> None:
    torch.manual_seed(0)
    net = TCPSmall(TCPConfig(image_height=36, image_width=64, channels=(8, 8, 16, 16), hidden=32,
                             attention_grid=(2, 4)))  # fmt: skip
    ckpt = tmp_path / "tcp.pt"
    torch.save({"kind": "tcp", "model_config": net.config.to_dict(), "model": net.state_dict(),
                "camera_hw": [36, 64]}, ckpt)  # fmt: skip
    for planner in ("only_traj", "only_ctrl", "merge_ctrl_traj"):
        agent = _agent("tcp_agent.py", f"{ckpt}+save", shim) if planner == "only_traj" else _agent(
            "tcp_agent.py", f"ckpt={ckpt},planner={planner}+save", shim)  # fmt: skip
        cam = next(s for s in agent.sensors() if s["id"] == "CAM_FRONT")
        # The clips' CAM_FRONT mount and FOV, at the size the checkpoint was trained on.
        assert (cam["x"], cam["z"], cam["fov"], cam["width"], cam["height"]) == (0.8, 1.6, 70.0, 64, 36)
        _valid(agent.run_step(_input(10.0, 3.0), 0.0))
