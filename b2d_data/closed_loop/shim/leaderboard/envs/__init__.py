"""``leaderboard.envs``: the sensor interface that hands an agent its sensor data."""
