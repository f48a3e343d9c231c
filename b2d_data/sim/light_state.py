"""Vehicle light states: CARLA's ``carla.VehicleLightState`` bits, read from and written as the simulator's names.

The simulator keeps a vehicle's lights as a name string (``"Special1|Special2"``); scenarios set the same flags
LB2.0 sets. Bench2Drive's annotations store ``str(vehicle.get_light_state()).split('.')[-1]``, and CARLA binds
the flags as a Boost.Python enum, whose ``str`` is a member's name only for a value that *is* one member (``NONE``,
``Special1``, ``All``) and the decimal value for any other combination (``Special1|Special2`` is ``"1536"``);
:func:`carla_str` gives that string.
"""

from __future__ import annotations

import logging

log = logging.getLogger(__name__)

#: carla.VehicleLightState members (LibCarla ``rpc/VehicleLightState.h``).
VEHICLE_LIGHT_BITS: dict[str, int] = {
    "NONE": 0,
    "Position": 0x1,
    "LowBeam": 0x1 << 1,
    "HighBeam": 0x1 << 2,
    "Brake": 0x1 << 3,
    "RightBlinker": 0x1 << 4,
    "LeftBlinker": 0x1 << 5,
    "Reverse": 0x1 << 6,
    "Fog": 0x1 << 7,
    "Interior": 0x1 << 8,
    "Special1": 0x1 << 9,
    "Special2": 0x1 << 10,
    "All": 0xFFFFFFFF,
}
_BY_LOWER = {name.lower(): bits for name, bits in VEHICLE_LIGHT_BITS.items()}
_NAME_OF_BITS = {bits: name for name, bits in VEHICLE_LIGHT_BITS.items()}
#: The bits an emergency vehicle's siren bar answers to (CARLA: Special1 is the siren, LB2.0 sets both).
SIREN_BITS = VEHICLE_LIGHT_BITS["Special1"] | VEHICLE_LIGHT_BITS["Special2"]


def light_bits(state: str | int | None) -> int:
    """The flag bits of a light state: ``"A|B"`` names (any case, ``,`` also separates), a decimal value or an int."""
    if state is None:
        return 0
    if isinstance(state, int):
        return int(state)
    bits = 0
    for part in str(state).replace(",", "|").split("|"):
        part = part.strip()
        if not part:
            continue
        if part.isdigit():
            bits |= int(part)
            continue
        value = _BY_LOWER.get(part.lower())
        if value is None:
            log.debug("unknown vehicle light name %r in %r", part, state)
        else:
            bits |= value
    return bits


def carla_str(state: str | int | None) -> str:
    """``str(carla.VehicleLightState(bits))``: the member's name where the bits are one member, else the decimal."""
    bits = light_bits(state)
    return _NAME_OF_BITS.get(bits, str(bits))


def sirens_on(state: str | int | None) -> bool:
    """Whether the siren bar flashes: Special1 or Special2 set."""
    return bool(light_bits(state) & SIREN_BITS)
