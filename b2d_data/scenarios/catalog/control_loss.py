"""ControlLoss (§2.2 #1): the ego loses grip over three patches of dirt debris.

Three flat debris props (``static.prop.dirtdebris01``, no collision) lie on the lane 14, 48 and 74 m after the
trigger point. As LB2.0's behaviour sequence, the patches act one after the other: from the moment the ego is
within 2 m of the current patch until it is more than 2 m from it, every tick's control of the ego gets noise:
throttle += N(±0.03, 0.01) and steer += N(±0.055, 0.015), the signs drawn at random per patch; only then is the
next patch watched. The scenario ends when the ego has driven 110 m after the trigger, or 110 − 74 = 36 m after
leaving the third patch. Only the route criteria apply.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

from b2d_data.format.transform import Transform
from b2d_data.scenarios.catalog.layout import Layout, any_lane, register_layouts
from b2d_data.scenarios.catalog.road_geometry import move_along, offset_transform
from b2d_data.scenarios.framework import Scenario, ScenarioContext, ScenarioSetupError, ScenarioStatus, register
from b2d_data.scenarios.triggers import DriveDistance, horizontal_distance
from b2d_data.sim.api import Snapshot, VehicleControl

log = logging.getLogger(__name__)

#: The debris blueprint (flat: the wheels roll over them); LB2.0 uses this one for all three patches.
DEBRIS_MODEL = "static.prop.dirtdebris01"


@dataclass
class _Patch:
    """One debris patch: where it lies and the noise it causes."""

    transform: Transform
    throttle_mean: float
    steer_mean: float
    active: bool = False
    passed: bool = False


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
        #: The index of the patch the sequence is at (3: all passed), and the drive after the last one.
        self.current = 0
        self._after_last = DriveDistance(self.end_distance - self.debris_distances[-1])

    def build(self) -> None:
        """The three debris patches on the lane."""
        for patch in self.patches:
            retries = [offset_transform(patch.transform, forward=f, z=0.01) for f in (0.5, -0.5)]
            self.debris.append(self.spawn(DEBRIS_MODEL, offset_transform(patch.transform, z=0.01), retries=retries))

    def update(self, snapshot: Snapshot) -> ScenarioStatus:
        """LB2.0's sequence: noise on within 2 m of the current patch, off beyond 2 m of it, then the next patch;
        SUCCESS after 110 m, or 36 m after the last patch."""
        ego = self.ctx.ego(snapshot)
        if ego is None:
            return ScenarioStatus.RUNNING
        done = self._after.check(ego)
        if self.current < len(self.patches):
            patch = self.patches[self.current]
            near = horizontal_distance(ego.location, patch.transform.location)
            if not patch.active and near < self.trigger_distance:
                patch.active = True
                log.debug("%s: noise on at (%.1f, %.1f)", self.name, ego.location.x, ego.location.y)
            elif patch.active and near > self.trigger_distance:
                patch.active, patch.passed = False, True
                self.current += 1
        elif self._after_last.check(ego):
            done = True
        return ScenarioStatus.SUCCESS if done else ScenarioStatus.RUNNING

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
