"""``leaderboard.envs.sensor_interface``: the buffer between the sensors and the agent's ``input_data``.

The Leaderboard's interface waits on a queue (up to 300 s in Bench2Drive) until every sensor delivered the frame.
Here the world is synchronous and the evaluator pushes every sensor's data for a frame before it calls the agent, so a
sensor without data for the asked frame is an error at once (:class:`SensorReceivedNoData` naming the sensors); the
frame's data of the other sensors is then kept for a retry of the same frame.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from b2d_data.closed_loop.sensor_config import OPENDRIVE_MAP, SensorConfigurationInvalid, SensorReceivedNoData

__all__ = ["GenericMeasurement", "SensorConfigurationInvalid", "SensorInterface", "SensorReceivedNoData"]

log = logging.getLogger(__name__)


@dataclass
class GenericMeasurement:
    """Data of a pseudo sensor (speedometer, OpenDRIVE map) with the frame it was read at."""

    data: Any
    frame: int


class SensorInterface:
    """Registered sensors and the data they delivered, handed out per frame as ``{tag: (frame, data)}``."""

    def __init__(self) -> None:
        self._sensors_objects: dict[str, Any] = {}
        self._sensor_types: dict[str, str] = {}
        self._data_buffers: list[tuple[str, int, Any]] = []
        self._opendrive_tag: str | None = None

    def register_sensor(self, tag: str, sensor_type: str, sensor: Any) -> None:
        """Register a sensor under its id; a tag used twice raises SensorConfigurationInvalid."""
        if tag in self._sensors_objects:
            raise SensorConfigurationInvalid(f"Duplicated sensor tag [{tag}]")
        self._sensors_objects[tag] = sensor
        self._sensor_types[tag] = sensor_type
        if sensor_type == OPENDRIVE_MAP:
            self._opendrive_tag = tag

    def update_sensor(self, tag: str, data: Any, frame: int) -> None:
        """Deliver one sensor's data of a frame; an unregistered tag raises SensorConfigurationInvalid."""
        if tag not in self._sensors_objects:
            raise SensorConfigurationInvalid(f"The sensor with tag [{tag}] has not been created!")
        self._data_buffers.append((tag, int(frame), data))

    def get_data(self, frame: int) -> dict[str, tuple[int, Any]]:
        """Every sensor's data of ``frame`` (the OpenDRIVE map only when it delivered); other frames' data is dropped.

        Raises :class:`SensorReceivedNoData` at once, naming the sensors without data for the frame.
        """
        frame = int(frame)
        data: dict[str, tuple[int, Any]] = {}
        for tag, data_frame, value in self._data_buffers:
            if data_frame == frame:
                data[tag] = (data_frame, value)  # a later delivery of the same frame wins, as with the queue
        missing = [tag for tag in self._sensors_objects if tag not in data and tag != self._opendrive_tag]
        if missing:
            # Keep what arrived for this frame, so that a caller who pushes the rest can ask again.
            self._data_buffers = [(tag, f, v) for tag, (f, v) in data.items()]
            raise SensorReceivedNoData(
                f"no data for frame {frame} from sensor(s) {', '.join(missing)} "
                "(the evaluator must deliver every sensor's data before the agent's step)"
            )
        self._data_buffers = []
        return data
