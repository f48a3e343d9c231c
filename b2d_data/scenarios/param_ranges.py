"""The ranges generated routes draw each scenario's XML parameters from: two named sets.

``training`` (the default) is read off CARLA Leaderboard 2.0's ``routes_training.xml`` (branch leaderboard-2.0,
``data/routes_training.xml``), the route set PDM-Lite-style data is collected on: for each type the smallest and
largest value of every numeric parameter the file sets and the values of its categorical ones. Obstacles and
actors lie much further out there (Accident 50–200 m, ConstructionObstacleTwoWays up to 300 m,
YieldToEmergencyVehicle 110–140 m behind) and flows are faster and denser (up to 21 m/s, gaps from 5 m).

``bench2drive220`` keeps the narrower ranges the placement drew before (expert-and-scenarios.md §2.2:
bench2drive220.xml's values, junction flows on their slower, sparser part).

Where the training set departs from a plain min/max of the file:

- Types absent from ``routes_training.xml`` (the Bench2Drive-only SignalizedJunctionLeftTurnEnterFlow and
  NonSignalizedJunctionLeftTurnEnterFlow) keep their bench2drive220 ranges in both sets.
- The LB2.0-only EnterActorFlowV2 (9 routes in the file: ``flow_speed`` 15–22, ``source_dist_interval`` from 15–20 to
  35–40) has no bench2drive220 route: ``bench2drive220`` draws it from the training ranges too. PriorityAtJunction
  (237 routes) has no parameter.
- Numbers are drawn as integers in [min, max] (the file's few decimals, e.g. ``flow_speed`` 8.3 and 16.6 m/s,
  lie inside); the upper end of a ``from``/``to`` interval is never drawn below its lower end.
- Typos are left out: CrossingBicycleFlow's ``source_dist_interval to="3255"`` (3 of 42) and ParkingCutIn's
  ``direction="40"`` (3 of 114).
- ``direction``: Accident, ConstructionObstacle, ParkedObstacle and StaticCutIn draw both sides equally often.
  DynamicObjectCrossing, ParkingCrossingPedestrian, ParkingCutIn and ParkingExit draw left as often as the file
  has it, counting its routes without a ``direction`` as right (the default): 12 of 351, 36 of 126, 27 of 111
  (the 3 typos left out) and 3 of 42; bench2drive220's ParkingCutIn 1 of 5. Left needs a one-way road's left
  kerb (a sidewalk, or a parking lane): of the generated towns only the ``downtown`` preset (Town104) has one
  (its one-way streets). In a town without one a left draw finds no place and the route is drawn again at the
  next place (``placement.make_routes`` logs it); ``make_routes(..., direction="left")`` draws that side only,
  which ``b2d-collect`` (``--preset``, and ``--scenario`` without ``--town``) uses to send its left draws of these
  types to Town104.
- DynamicObjectCrossing's ``blocker_model`` is drawn as often as the file has each model, with the nearest props
  of our blueprint library for the three it lacks (:data:`~b2d_data.scenarios.catalog.actor_choices.
  TRAINING_BLOCKER_MODELS`).
- Parameters the file sets in only some scenarios (Accident's ``speed`` in 45 of 111) are drawn for every route.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from b2d_data.scenarios.catalog.actor_choices import BLOCKER_MODELS, TRAINING_BLOCKER_MODELS


@dataclass(frozen=True)
class IntRange:
    """Whole numbers from ``lo`` to ``hi`` inclusive (a single value when equal: nothing is drawn)."""

    lo: int
    hi: int

    def __post_init__(self) -> None:
        if self.lo > self.hi:
            raise ValueError(f"empty range {self.lo}..{self.hi}")

    def draw(self, rng: np.random.Generator, lo: int | None = None) -> int:
        """A value in the range (at least ``lo`` when given and inside it)."""
        low = self.lo if lo is None else min(max(self.lo, lo), self.hi)
        return low if low == self.hi else int(rng.integers(low, self.hi + 1))


@dataclass(frozen=True)
class FloatRange:
    """Decimals from ``lo`` to ``hi``, written with ``digits`` decimals."""

    lo: float
    hi: float
    digits: int = 2

    def draw(self, rng: np.random.Generator) -> str:
        """A value in the range, as the XML text."""
        return f"{rng.uniform(self.lo, self.hi):.{self.digits}f}"


@dataclass(frozen=True)
class Choice:
    """One of ``values`` (a single value: nothing is drawn), equally likely or in proportion to ``weights``."""

    values: tuple[str, ...]
    #: How often each value occurs in the source file (None: equally often).
    weights: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if self.weights is not None and (len(self.weights) != len(self.values) or min(self.weights) <= 0):
            raise ValueError(f"weights {self.weights} must be positive, one per value of {self.values}")

    def draw(self, rng: np.random.Generator) -> str:
        """One of the values."""
        if len(self.values) == 1:
            return self.values[0]
        if self.weights is None:
            return self.values[int(rng.integers(len(self.values)))]
        # one uniform draw against the cumulative counts: value k for u × total in [sum(w[:k]), sum(w[:k + 1]))
        point = float(rng.uniform()) * sum(self.weights)
        return self.values[int(np.searchsorted(np.cumsum(self.weights), point, side="right"))]


@dataclass(frozen=True)
class Interval:
    """A ``from``/``to`` pair (``source_dist_interval``, ``frequency``): ``to`` is never below ``from``."""

    lo: IntRange
    hi: IntRange

    def draw(self, rng: np.random.Generator) -> dict[str, str]:
        """The XML attributes ``from`` and ``to``."""
        start = self.lo.draw(rng)
        return {"from": str(start), "to": str(self.hi.draw(rng, lo=start))}


Spec = IntRange | FloatRange | Choice | Interval


@dataclass(frozen=True)
class ParamSet:
    """A named set of ranges: per scenario type, its parameters in drawing order."""

    name: str
    types: Mapping[str, Mapping[str, Spec]] = field(default_factory=dict)

    def ranges(self, scenario_type: str) -> Mapping[str, Spec]:
        """The parameters ``scenario_type`` draws (empty when it has none)."""
        return self.types.get(scenario_type, MappingProxyType({}))

    def int_range(self, scenario_type: str, name: str) -> IntRange | None:
        """The range of a whole-number parameter, None when the type does not draw it."""
        spec = self.ranges(scenario_type).get(name)
        return spec if isinstance(spec, IntRange) else None

    def choices(self, scenario_type: str, name: str) -> tuple[str, ...]:
        """The values of a categorical parameter (empty when the type does not draw it)."""
        spec = self.ranges(scenario_type).get(name)
        return spec.values if isinstance(spec, Choice) else ()

    def pinned(self, scenario_type: str, name: str, value: str) -> ParamSet:
        """This set (same name) with ``scenario_type``'s categorical ``name`` fixed to ``value``, one of its values."""
        if value not in self.choices(scenario_type, name):
            raise ValueError(f"{scenario_type} draws no {name}={value!r} in the {self.name!r} set")
        types = dict(self.types)
        types[scenario_type] = MappingProxyType({**self.ranges(scenario_type), name: Choice((value,))})
        return ParamSet(self.name, MappingProxyType(types))

    def draw(self, scenario_type: str, rng: np.random.Generator) -> dict[str, dict[str, str]]:
        """XML parameters of one scenario, drawn in order (the ``value`` attribute, or ``from``/``to``)."""
        out: dict[str, dict[str, str]] = {}
        for name, spec in self.ranges(scenario_type).items():
            if isinstance(spec, Interval):
                out[name] = spec.draw(rng)
            elif isinstance(spec, IntRange):
                out[name] = {"value": str(spec.draw(rng))}
            else:
                out[name] = {"value": spec.draw(rng)}
        return out


def _r(lo: int, hi: int) -> IntRange:
    return IntRange(lo, hi)


def _iv(lo: tuple[int, int], hi: tuple[int, int]) -> Interval:
    return Interval(IntRange(*lo), IntRange(*hi))


def _flow(speed: tuple[int, int], start: tuple[int, int], end: tuple[int, int]) -> dict[str, Spec]:
    return {"flow_speed": _r(*speed), "source_dist_interval": _iv(start, end)}


_RIGHT = Choice(("right",))
_BOTH = Choice(("right", "left"))
_BLOCKERS = Choice(BLOCKER_MODELS)


def _sides(right: int, left: int) -> Choice:
    """``direction`` as often right and left as a route file has it (routes without one count as right, the
    scenarios' default)."""
    return Choice(("right", "left"), (right, left))

#: Bench2Drive's evaluation ranges, as drawn before the training set existed (order = drawing order).
_BENCH2DRIVE220: dict[str, dict[str, Spec]] = {
    "Accident": {"distance": _r(40, 44), "direction": _RIGHT, "speed": _r(53, 57)},
    "ParkedObstacleTwoWays": {"distance": _r(40, 44), "frequency": _iv((31, 56), (106, 151))},
    "ParkedObstacle": {"distance": _r(40, 43), "direction": _RIGHT, "speed": _r(40, 59)},
    "ConstructionObstacle": {"distance": _r(40, 45), "direction": _RIGHT, "speed": _r(47, 55)},
    "AccidentTwoWays": {"distance": _r(40, 44), "frequency": _iv((32, 63), (109, 184))},
    "ConstructionObstacleTwoWays": {"distance": _r(40, 45), "frequency": _iv((43, 70), (129, 200))},
    "HazardAtSideLane": {"distance": _r(41, 45), "speed": _r(32, 59), "bicycle_drive_distance": _r(40, 101),
                         "bicycle_speed": _r(6, 12)},
    "HazardAtSideLaneTwoWays": {"distance": _r(41, 45), "frequency": _r(75, 100),
                                "bicycle_drive_distance": _r(80, 116), "bicycle_speed": _r(7, 11)},
    "VehicleOpensDoorTwoWays": {"distance": _r(37, 59), "direction": _RIGHT, "frequency": _iv((30, 40), (89, 98))},
    "InvadingTurn": {"distance": _r(50, 60), "offset": FloatRange(0.18, 0.34)},
    # the blocker first: the order the placement drew them in before the sets existed (same routes per seed)
    "DynamicObjectCrossing": {"blocker_model": _BLOCKERS, "distance": _r(40, 50), "direction": _RIGHT,
                              "crossing_angle": _r(0, 11)},
    "ParkingCrossingPedestrian": {"distance": _r(36, 45), "direction": _RIGHT, "crossing_angle": _r(0, 12)},
    # bench2drive220.xml: 1 of its 5 ParkingCutIn routes is left
    "ParkingCutIn": {"direction": _sides(4, 1)},
    "StaticCutIn": {"distance": _r(40, 45), "direction": _RIGHT},
    # Junction flows: the slower, sparser part of §2.2's ranges. The expert turns through a gap only when no flow
    # car's 2 s forecast meets its own; denser or faster flows (down to 1 s headways) leave it waiting for good.
    "SignalizedJunctionLeftTurn": _flow((9, 10), (20, 24), (26, 28)),
    "NonSignalizedJunctionLeftTurn": _flow((8, 10), (20, 24), (26, 30)),
    "SignalizedJunctionLeftTurnEnterFlow": _flow((8, 10), (20, 24), (26, 30)),
    "NonSignalizedJunctionLeftTurnEnterFlow": _flow((8, 10), (17, 19), (26, 30)),
    "EnterActorFlow": _flow((12, 14), (25, 30), (33, 39)),
    "CrossingBicycleFlow": _flow((8, 9), (13, 15), (25, 30)),
    "SignalizedJunctionRightTurn": _flow((10, 12), (20, 24), (28, 38)),
    "NonSignalizedJunctionRightTurn": _flow((8, 11), (18, 22), (27, 30)),
    "InterurbanActorFlow": _flow((15, 16), (42, 53), (78, 98)),
    "InterurbanAdvancedActorFlow": _flow((16, 18), (36, 42), (84, 94)),
    "MergerIntoSlowTraffic": _flow((9, 10), (14, 16), (33, 42)),
    "MergerIntoSlowTrafficV2": _flow((10, 10), (11, 14), (30, 34)),
    "HighwayExit": _flow((10, 15), (11, 20), (33, 46)),
    # LB2.0-only: no bench2drive220 route to read a range off; the training ranges (routes_training.xml)
    "EnterActorFlowV2": _flow((15, 22), (15, 20), (35, 40)),
    "YieldToEmergencyVehicle": {"distance": _r(26, 30)},
    "ParkingExit": {"direction": _RIGHT, "front_vehicle_distance": _r(9, 9), "behind_vehicle_distance": _r(9, 9)},
}  # fmt: skip

#: LB2.0 routes_training.xml, min/max per type (see the module docstring for the exceptions).
_TRAINING: dict[str, dict[str, Spec]] = {
    "Accident": {"distance": _r(50, 200), "direction": _BOTH, "speed": _r(40, 70)},
    "ParkedObstacleTwoWays": {"distance": _r(50, 130), "frequency": _iv((15, 75), (80, 200))},
    "ParkedObstacle": {"distance": _r(50, 160), "direction": _BOTH, "speed": _r(40, 70)},
    "ConstructionObstacle": {"distance": _r(70, 200), "direction": _BOTH, "speed": _r(40, 60)},
    "AccidentTwoWays": {"distance": _r(70, 170), "frequency": _iv((30, 75), (105, 220))},
    "ConstructionObstacleTwoWays": {"distance": _r(70, 300), "frequency": _iv((35, 75), (80, 220))},
    "HazardAtSideLane": {"distance": _r(50, 90), "speed": _r(30, 60), "bicycle_drive_distance": _r(60, 200),
                         "bicycle_speed": _r(8, 15)},
    "HazardAtSideLaneTwoWays": {"distance": _r(40, 135), "frequency": _r(75, 140),
                                "bicycle_drive_distance": _r(40, 300), "bicycle_speed": _r(5, 12)},
    "VehicleOpensDoorTwoWays": {"distance": _r(35, 80), "direction": _RIGHT, "frequency": _iv((25, 40), (80, 105))},
    "InvadingTurn": {"distance": _r(90, 200), "offset": FloatRange(0.15, 0.40)},
    "DynamicObjectCrossing": {"blocker_model": Choice(*zip(*TRAINING_BLOCKER_MODELS)), "distance": _r(15, 70),
                              "direction": _sides(339, 12), "crossing_angle": _r(0, 20)},
    "ParkingCrossingPedestrian": {"distance": _r(30, 50), "direction": _sides(90, 36), "crossing_angle": _r(5, 15)},
    "ParkingCutIn": {"direction": _sides(84, 27)},
    "StaticCutIn": {"distance": _r(80, 170), "direction": _BOTH},
    "SignalizedJunctionLeftTurn": _flow((8, 19), (10, 40), (40, 85)),
    "NonSignalizedJunctionLeftTurn": _flow((8, 20), (10, 80), (40, 110)),
    "SignalizedJunctionLeftTurnEnterFlow": _BENCH2DRIVE220["SignalizedJunctionLeftTurnEnterFlow"],
    "NonSignalizedJunctionLeftTurnEnterFlow": _BENCH2DRIVE220["NonSignalizedJunctionLeftTurnEnterFlow"],
    "EnterActorFlow": _flow((15, 20), (15, 30), (30, 70)),
    "CrossingBicycleFlow": _flow((5, 10), (5, 30), (18, 60)),
    "SignalizedJunctionRightTurn": _flow((10, 18), (10, 40), (35, 80)),
    "NonSignalizedJunctionRightTurn": _flow((5, 21), (10, 50), (30, 110)),
    "InterurbanActorFlow": _flow((15, 20), (25, 65), (75, 120)),
    "InterurbanAdvancedActorFlow": _flow((15, 18), (20, 50), (75, 105)),
    "MergerIntoSlowTraffic": _flow((8, 17), (10, 20), (30, 50)),
    "MergerIntoSlowTrafficV2": _flow((10, 10), (15, 15), (30, 30)),
    "HighwayExit": _flow((10, 15), (10, 25), (25, 50)),
    "EnterActorFlowV2": _BENCH2DRIVE220["EnterActorFlowV2"],
    "YieldToEmergencyVehicle": {"distance": _r(110, 140)},
    "ParkingExit": {"direction": _sides(39, 3), "front_vehicle_distance": _r(9, 9),
                    "behind_vehicle_distance": _r(9, 9)},
}  # fmt: skip


def _frozen(types: dict[str, dict[str, Spec]]) -> Mapping[str, Mapping[str, Spec]]:
    return MappingProxyType({k: MappingProxyType(dict(v)) for k, v in types.items()})


TRAINING = ParamSet("training", _frozen(_TRAINING))
BENCH2DRIVE220 = ParamSet("bench2drive220", _frozen(_BENCH2DRIVE220))
#: The sets by name; the first is the default.
PARAM_SETS: Mapping[str, ParamSet] = MappingProxyType({s.name: s for s in (TRAINING, BENCH2DRIVE220)})
DEFAULT_PARAMS = TRAINING.name


def param_set(which: str | ParamSet) -> ParamSet:
    """The set named ``which`` (a :class:`ParamSet` passes through); ValueError names the known sets."""
    if isinstance(which, ParamSet):
        return which
    try:
        return PARAM_SETS[which]
    except KeyError:
        raise ValueError(f"unknown parameter set {which!r}; choose one of {', '.join(PARAM_SETS)}") from None
