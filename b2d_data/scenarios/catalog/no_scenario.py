"""Plain routes (``NoScenario``): background traffic only, through one junction, any turn."""

from __future__ import annotations

from b2d_data.format.scenario_types import NO_SCENARIO
from b2d_data.scenarios.catalog.layout import Layout, register_layouts


register_layouts({
    # Plain routes with background traffic only (no <scenario>): through one junction, any turn.
    NO_SCENARIO: Layout(
        "junction", "a junction the route crosses", turns=("left", "right", "straight"), approach=(30.0, 40.0),
        departure=(30.0, 40.0)),
})  # fmt: skip
