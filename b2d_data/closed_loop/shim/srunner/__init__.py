"""Stand-in for the parts of CARLA's scenario_runner (``srunner``) that Leaderboard agents import."""
