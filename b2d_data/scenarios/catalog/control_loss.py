"""ControlLoss (§2.2 #1): the ego loses grip over three patches of dirt debris.

Three flat debris props (no collision) lie on the lane 14, 48 and 74 m after the trigger point. From the moment
the ego is within 2 m of a patch until it is 2 m past it, every tick's control of the ego gets noise: throttle +=
N(±0.03, 0.01) and steer += N(±0.055, 0.015), the signs drawn at random per patch. The scenario ends when the
ego has driven 110 m after the trigger. Only the route criteria apply.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

from b2d_data.format.transform import Location, Transform
from b2d_data.scenarios.catalog.layout import Layout, any_lane, register_layouts
from b2d_data.scenarios.catalog.road_geometry import move_along, offset_transform
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, horizontal_distance
from b2d_data.sim.api import Snapshot, VehicleControl

log = logging.getLogger(__name__)

#: The debris blueprints (flat: the wheels roll over them).
DEBRIS_MODELS = ("static.prop.dirtdebris01", "static.prop.dirtdebris02", "static.prop.dirtdebris03")


@dataclass
class _Patch:
    """One debris patch: where it lies and the noise it causes."""

    transform: Transform
    throttle_mean: float
    steer_mean: float
    active: bool = False
    passed: bool = False

    def ahead_of(self, location: Location) -> float:
        """How far (m) ``location`` lies beyond the patch along the lane."""
        f = self.transform.get_forward_vector()
        loc = self.transform.location
        return f.x * (location.x - loc.x) + f.y * (location.y - loc.y)


@register
class ControlLoss(Scenario):
    """Noise on the ego's controls over three debris patches."""

    xml_type = "ControlLoss"
    scenario_timeout = None
    timeout_test = False
    debris_distances = (14.0, 48.0, 74.0)
    trigger_distance = 2.0
    throttle_noise = (0.03, 0.01)
    steer_noise = (0.055, 0.015)
    end_distance = 110.0

    def __init__(self, ctx: ScenarioContext) -> None:
        super().__init__(ctx)
        self.patches: list[_Patch] = []
        for d in self.debris_distances:
            wp = move_along(self.trigger_waypoint, d)
            if wp is None:
                raise ScenarioSetupError(f"{self.name}: the lane ends before the debris {d:.0f} m after the trigger")
            signs = ctx.rng.choice([-1.0, 1.0], size=2)
            self.patches.append(
                _Patch(wp.transform, float(signs[0]) * self.throttle_noise[0], float(signs[1]) * self.steer_noise[0])
            )
        self.debris: list[int] = []
        self._after = DriveDistance(self.end_distance)

    def build(self) -> None:
        """The three debris patches on the lane."""
        for patch in self.patches:
            model = DEBRIS_MODELS[int(self.ctx.rng.integers(len(DEBRIS_MODELS)))]
            retries = [offset_transform(patch.transform, forward=f, z=0.01) for f in (0.5, -0.5)]
            self.debris.append(self.spawn(model, offset_transform(patch.transform, z=0.01), retries=retries))

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """Switch the noise on near a patch and off 2 m past it; SUCCESS after 110 m."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        for patch in self.patches:
            if patch.passed:
                continue
            if not patch.active and horizontal_distance(ego.location, patch.transform.location) < self.trigger_distance:
                patch.active = True
                log.debug("%s: noise on at (%.1f, %.1f)", self.name, ego.location.x, ego.location.y)
            if patch.active and patch.ahead_of(ego.location) > self.trigger_distance:
                patch.active, patch.passed = False, True
        return ScenarioStatus.SUCCESS if self._after.check(ego) else ScenarioStatus.RUNNING

    @property
    def noisy(self) -> bool:
        """Whether the ego's controls are being perturbed now."""
        return any(p.active for p in self.patches)

    def adjust_control(self, control: VehicleControl) -> VehicleControl:
        """The ego's control with this tick's noise added (clipped to the valid ranges)."""
        patch = next((p for p in self.patches if p.active), None)
        if patch is None:
            return control
        rng = self.ctx.rng
        throttle = control.throttle + float(rng.normal(patch.throttle_mean, self.throttle_noise[1]))
        steer = control.steer + float(rng.normal(patch.steer_mean, self.steer_noise[1]))
        return replace(control, throttle=min(max(throttle, 0.0), 1.0), steer=min(max(steer, -1.0), 1.0))


# ------------------------------------------------------------------------------------------------ placement


register_layouts({
    "ControlLoss": Layout("road", "any driving lane, 115 m junction-free", any_lane, clear_after=115.0,
                          length=130.0),
})  # fmt: skip
