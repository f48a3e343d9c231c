"""Stand-in for the parts of the CARLA Leaderboard 2.0 (Bench2Drive's fork) that agents import."""
