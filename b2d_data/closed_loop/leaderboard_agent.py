"""A Leaderboard 2.0 agent as the route runner's :class:`~b2d_data.scenarios.route_runner.Agent`.

What Bench2Drive's ``leaderboard_evaluator`` and ``AgentWrapper`` do around a user's agent, in the same order:
load the module and instantiate the class ``get_entry_point()`` names (its ``__init__`` finds the hero), hand it the
route (``set_global_plan`` with the dense route as GPS and world coordinates, before ``setup``), call
``setup(config + "+" + save_name)``, validate its ``sensors()``, mount them with the wrapper's fixed attributes, tick
the world ten times, then each tick push every sensor's data into the agent's ``sensor_interface`` and call the
agent. Its control drives the ego. Failures become the Leaderboard's statuses through
:class:`~b2d_data.scenarios.route_runner.RouteFailure`: set-up errors "Agent couldn't be set up", invalid sensors
"Agent's sensors were invalid", errors (or a step slower than the step timeout) "Agent crashed".

This module runs only in route processes, where :data:`b2d_data.closed_loop.SHIM_DIR` is on ``sys.path``; it imports
the stand-in ``carla`` / ``leaderboard`` / ``srunner`` modules lazily, after that.
"""

from __future__ import annotations

import importlib
import logging
import math
import sys
import time
import traceback
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from b2d_data.closed_loop import bridge as route_bridge
from b2d_data.closed_loop.agent_thread import AgentThread, AgentTimeout
from b2d_data.closed_loop.sensor_config import (
    PseudoSensor,
    SensorConfigurationInvalid,
    preprocess_sensor_spec,
    validate_sensor_configuration,
)
from b2d_data.scenarios import statistics
from b2d_data.scenarios.route_runner import RouteFailure
from b2d_data.sim.api import FIXED_DELTA_SECONDS, ActorState, ScenarioHint, SensorMount, Simulator, Snapshot
from b2d_data.sim.api import VehicleControl as SimControl

log = logging.getLogger(__name__)

#: Failure messages of the Leaderboard (``FAILURE_MESSAGES`` of Bench2Drive's evaluator) that agents cause.
AGENT_SETUP_FAILURE = "Agent couldn't be set up"
SENSORS_INVALID_FAILURE = "Agent's sensors were invalid"
AGENT_CRASHED_FAILURE = statistics.AGENT_CRASHED_FAILURE

#: Ticks the agent wrapper runs after mounting the sensors, before the route starts ("some sensors miss sending
#: data during the first ticks").
WARMUP_TICKS = 10
#: What the evaluator passes to the agent's constructor (``carla_host``, ``carla_port``, ``debug``).
AGENT_HOST, AGENT_PORT, AGENT_DEBUG = "localhost", 2000, 0
SPEEDOMETER = "sensor.speedometer"
OPENDRIVE_MAP = "sensor.opendrive_map"


class AgentLoadError(Exception):
    """The agent file cannot be imported or does not name its class through ``get_entry_point()``."""


def load_agent_module(path: Path) -> ModuleType:
    """Import the agent file as the Leaderboard does: its folder first on ``sys.path``, imported by its stem."""
    path = Path(path).resolve()
    if not path.is_file():
        raise AgentLoadError(f"agent file {path} does not exist")
    folder = str(path.parent)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    try:
        module = importlib.import_module(path.stem)
    except Exception as exc:
        raise AgentLoadError(f"cannot import agent file {path}: {type(exc).__name__}: {exc}") from exc
    if not callable(getattr(module, "get_entry_point", None)):
        raise AgentLoadError(f"agent file {path} has no get_entry_point() naming its agent class")
    return module


def agent_class(module: ModuleType) -> type:
    """The class ``module.get_entry_point()`` names."""
    name = module.get_entry_point()
    cls = getattr(module, str(name), None)
    if not isinstance(cls, type):
        raise AgentLoadError(f"get_entry_point() of {module.__file__} returns {name!r}, which is not a class there")
    return cls


def _summary(exc: BaseException) -> str:
    """``Type: message`` of an exception (the last line of its traceback)."""
    return "".join(traceback.format_exception_only(type(exc), exc)).strip()


def forward_speed(ego: ActorState) -> float:
    """The speedometer's value: velocity along the forward axis from pitch and yaw (``SpeedometerReader``)."""
    pitch, yaw = math.radians(ego.transform.rotation.pitch), math.radians(ego.transform.rotation.yaw)
    v = ego.velocity
    return v.x * math.cos(pitch) * math.cos(yaw) + v.y * math.cos(pitch) * math.sin(yaw) + v.z * math.sin(pitch)


def metric_info_of(ego: ActorState) -> dict[str, list[float]]:
    """One step of ``metric_info.json``: what Bench2Drive's ``get_metric_info`` reads from the hero."""
    t = ego.transform
    fwd, right = t.get_forward_vector(), t.get_right_vector()
    return {
        "acceleration": ego.acceleration.to_list(),
        "angular_velocity": ego.angular_velocity.to_list(),
        "forward_vector": fwd.to_list(),
        "right_vector": right.to_list(),
        "location": t.location.to_list(),
        "rotation": [float(t.rotation.roll), float(t.rotation.pitch), float(t.rotation.yaw)],
    }


def to_sim_control(control: Any) -> SimControl:
    """The agent's ``carla.VehicleControl`` as the simulator's control, clamped as CARLA clamps it.

    A missing or non-numeric field, or NaN, is the agent's error (:class:`ValueError` naming the field).
    """
    if control is None:
        raise ValueError("run_step returned None instead of a carla.VehicleControl")
    values: dict[str, float] = {}
    for name in ("throttle", "steer", "brake"):
        try:
            value = float(getattr(control, name))
        except (AttributeError, TypeError, ValueError):
            raise ValueError(f"run_step returned {type(control).__name__} without a numeric {name!r}") from None
        if not math.isfinite(value):
            raise ValueError(f"run_step returned {name}={value}")
        values[name] = value
    return SimControl(
        throttle=min(max(values["throttle"], 0.0), 1.0),
        steer=min(max(values["steer"], -1.0), 1.0),
        brake=min(max(values["brake"], 0.0), 1.0),
        hand_brake=bool(getattr(control, "hand_brake", False)),
        reverse=bool(getattr(control, "reverse", False)),
        # the Leaderboard forces manual_gear_shift off whatever the agent set
        manual_gear_shift=False,
        gear=int(getattr(control, "gear", 0) or 0),
    )


@dataclass(frozen=True)
class AgentSettings:
    """How to run the agent: its file, the configuration string, the track and the time limits (seconds)."""

    path: Path
    config: str = ""
    track: str = "SENSORS"
    setup_timeout: float = 600.0
    step_timeout: float = 600.0
    warmup_ticks: int = WARMUP_TICKS
    record_metric_info: bool = True


@dataclass
class AgentTimings:
    """Wall seconds spent in the agent's set-up, its steps, and reading its sensors."""

    setup: float = 0.0
    steps: float = 0.0
    sensors: float = 0.0
    warmup: float = 0.0
    step_count: int = 0


@dataclass
class _Pseudo:
    """A pseudo sensor the evaluator feeds itself (speedometer, OpenDRIVE map)."""

    sensor_id: str
    type_id: str
    period: float
    last_sent: float | None = None


class LeaderboardAgent:
    """Drives the ego with a Leaderboard agent; ``start`` is the route runner's ``on_start`` hook."""

    def __init__(
        self,
        settings: AgentSettings,
        sim: Simulator,
        save_name: str,
        route: Any | None = None,
    ) -> None:
        self.settings = settings
        self.sim = sim
        self.save_name = save_name
        self.route = route
        self.metric_info: dict[int, dict[str, list[float]]] = {}
        self.timings = AgentTimings()
        self.sensor_ids: list[str] = []
        self._thread = AgentThread()
        self._agent: Any = None
        self._bridge: route_bridge.RouteBridge | None = None
        self._pseudo: list[_Pseudo] = []
        self._has_physical = False
        self._xodr: str | None = None

    @property
    def stuck(self) -> bool:
        """Whether an agent call outlived its limit (the process must not wait for the agent thread)."""
        return self._thread.stuck

    # ------------------------------------------------------------------------------------------------ set-up

    def start(self, ego_id: int) -> None:
        """Install the bridge, set the agent up, mount its sensors and run the warm-up ticks."""
        sim = self.sim
        # Spawning an actor ticks a synchronous CARLA world once (CarlaDataProvider.request_new_actor): the hero is
        # in the world, and in the snapshot, before the agent is created and looks for it.
        self._bridge = route_bridge.RouteBridge(sim=sim, map=sim.map, ego_id=ego_id, snapshot=sim.tick(),
                                                route=self.route)  # fmt: skip
        route_bridge.install(self._bridge)
        t0 = time.perf_counter()
        try:
            specs = self._thread.call(self._set_up, timeout=self.settings.setup_timeout)
        except AgentTimeout as exc:
            raise RouteFailure(AGENT_SETUP_FAILURE, f"set-up took longer than {self.settings.setup_timeout:g} s "
                               f"({exc})") from None  # fmt: skip
        except SensorConfigurationInvalid as exc:
            raise RouteFailure(SENSORS_INVALID_FAILURE, str(exc)) from None
        except Exception as exc:  # noqa: BLE001 - the Leaderboard records any set-up error the same way
            log.error("the agent could not be set up:\n%s", "".join(traceback.format_exception(exc)))
            raise RouteFailure(AGENT_SETUP_FAILURE, _summary(exc)) from None
        finally:
            self.timings.setup = time.perf_counter() - t0
        self._mount(ego_id, specs)
        t1 = time.perf_counter()
        for _ in range(self.settings.warmup_ticks):
            self._bridge.observe(sim.tick())
        self.timings.warmup = time.perf_counter() - t1

    def _set_up(self) -> list[dict[str, Any]]:
        """On the agent thread: import, construct, hand over the route, ``setup``, validate the sensors."""
        module = load_agent_module(self.settings.path)
        cls = agent_class(module)
        agent = cls(AGENT_HOST, AGENT_PORT, AGENT_DEBUG)
        self._agent = agent
        gps_route, world_route = self._global_plan()
        agent.set_global_plan(gps_route, world_route)
        agent.setup(f"{self.settings.config}+{self.save_name}")
        sensors = agent.sensors()
        if not isinstance(sensors, (list, tuple)):
            raise SensorConfigurationInvalid(f"sensors() returned {type(sensors).__name__}, not a list of dicts")
        validate_sensor_configuration(sensors, agent.track, self.settings.track)
        return list(sensors)

    def _global_plan(self) -> tuple[list[tuple[dict[str, float], Any]], list[tuple[Any, Any]]]:
        """The dense route as the Leaderboard hands it over: GPS dicts and ``carla.Transform`` with RoadOptions."""
        carla = importlib.import_module("carla")
        manipulation = importlib.import_module("leaderboard.utils.route_manipulation")
        provider = importlib.import_module("srunner.scenariomanager.carla_data_provider").CarlaDataProvider
        road_option = importlib.import_module("agents.navigation.local_planner").RoadOption
        lat_ref, lon_ref = manipulation._get_latlon_ref(provider.get_world())
        world_route, gps_route = [], []
        for waypoint, option in self.route:
            t = waypoint.transform
            transform = carla.Transform(
                carla.Location(x=t.location.x, y=t.location.y, z=t.location.z),
                carla.Rotation(pitch=t.rotation.pitch, yaw=t.rotation.yaw, roll=t.rotation.roll),
            )
            command = road_option(int(option))
            world_route.append((transform, command))
            gps_route.append((manipulation._location_to_gps(lat_ref, lon_ref, transform.location), command))
        return gps_route, world_route

    def _mount(self, ego_id: int, specs: Sequence[dict[str, Any]]) -> None:
        """Mount the physical sensors and register every sensor with the agent's sensor interface."""
        mounts: list[SensorMount] = []
        try:
            for spec in specs:
                mount = preprocess_sensor_spec(spec, FIXED_DELTA_SECONDS)
                if isinstance(mount, PseudoSensor):
                    period = 1.0 / mount.reading_frequency if mount.reading_frequency > 0 else 0.0
                    self._pseudo.append(_Pseudo(mount.sensor_id, mount.type_id, period))
                else:
                    mounts.append(mount)
                self._agent.sensor_interface.register_sensor(str(spec["id"]), str(spec["type"]), None)
                self.sensor_ids.append(str(spec["id"]))
        except SensorConfigurationInvalid as exc:
            raise RouteFailure(SENSORS_INVALID_FAILURE, str(exc)) from None
        except (KeyError, TypeError, ValueError) as exc:
            raise RouteFailure(SENSORS_INVALID_FAILURE, f"bad sensor specification: {_summary(exc)}") from None
        if mounts:
            self.sim.attach_sensors(ego_id, mounts)
            self._has_physical = True
        log.info("agent sensors: %s", ", ".join(f"{s['id']} ({s['type']})" for s in specs) or "none")

    # ------------------------------------------------------------------------------------------------ steps

    def run_step(self, snapshot: Snapshot, hints: Sequence[ScenarioHint]) -> SimControl:
        """One tick: update the bridge, deliver the sensor data, call the agent, return its control."""
        bridge = self._bridge
        assert bridge is not None and self._agent is not None, "start() must run before run_step()"
        bridge.advance(snapshot, hints)
        ego = snapshot.actors[bridge.ego_id]
        if self.settings.record_metric_info:
            self.metric_info[bridge.ticks - 1] = metric_info_of(ego)
        t0 = time.perf_counter()
        self._deliver(snapshot, ego, bridge.game_time())
        t1 = time.perf_counter()
        try:
            control = self._thread.call(self._agent, timeout=self.settings.step_timeout)
        except AgentTimeout:
            raise RouteFailure(AGENT_CRASHED_FAILURE, f"the agent's step at tick {bridge.ticks} took longer than "
                               f"{self.settings.step_timeout:g} s (--step-timeout)") from None  # fmt: skip
        except Exception as exc:  # noqa: BLE001 - any agent error ends the route as the Leaderboard does
            if type(exc).__name__ == "SensorReceivedNoData":
                # the Leaderboard treats a sensor without data as the simulation's fault, not the agent's
                raise RouteFailure(statistics.SIMULATION_CRASHED_FAILURE, _summary(exc)) from None
            log.error("the agent crashed at step %d:\n%s", bridge.ticks, "".join(traceback.format_exception(exc)))
            raise RouteFailure(AGENT_CRASHED_FAILURE, _summary(exc)) from None
        finally:
            self.timings.sensors += t1 - t0
            self.timings.steps += time.perf_counter() - t1
            self.timings.step_count += 1
        try:
            return to_sim_control(control)
        except ValueError as exc:
            raise RouteFailure(AGENT_CRASHED_FAILURE, str(exc)) from None

    def _deliver(self, snapshot: Snapshot, ego: ActorState, game_time: float) -> None:
        """Push this tick's data of every sensor into the agent's sensor interface."""
        interface = self._agent.sensor_interface
        frame = snapshot.frame
        if self._has_physical:
            for sensor_id, data in self.sim.read_attached_sensors().items():
                interface.update_sensor(sensor_id, data, frame)
        for pseudo in self._pseudo:
            if pseudo.type_id == SPEEDOMETER:
                interface.update_sensor(pseudo.sensor_id, {"speed": forward_speed(ego)}, frame)
            elif pseudo.last_sent is None or game_time - pseudo.last_sent > pseudo.period:
                # the OpenDRIVE reader sends at the first tick, then at its own reading frequency
                interface.update_sensor(pseudo.sensor_id, {"opendrive": self._opendrive()}, frame)
                pseudo.last_sent = game_time

    def _opendrive(self) -> str:
        if self._xodr is None:
            path = getattr(self.sim.map, "path", None)
            self._xodr = Path(path).read_text(encoding="utf-8") if path else ""
        return self._xodr

    # ------------------------------------------------------------------------------------------------ end

    def close(self) -> None:
        """``destroy()`` the agent (unless its thread is stuck) and uninstall the bridge; never raises."""
        try:
            # a call still running (timed out, or interrupted by SIGTERM while the agent computes) keeps the thread:
            # destroy() would only queue behind it
            if self._agent is not None and not self._thread.busy:
                destroy = getattr(self._agent, "destroy", None)
                if callable(destroy):
                    self._thread.call(destroy, timeout=self.settings.setup_timeout)
        except Exception:
            log.exception("the agent's destroy() failed")
        finally:
            self._thread.close()
            route_bridge.install(None)

