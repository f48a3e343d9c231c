"""Stand-in for the parts of CARLA's ``agents`` package (PythonAPI/carla/agents) that Leaderboard agents import."""
