"""``agents.navigation``: RoadOption and the global route planner."""
