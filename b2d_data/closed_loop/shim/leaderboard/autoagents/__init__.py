"""``leaderboard.autoagents``: the agent base class and the sensor rules of the agent wrapper."""
