"""``leaderboard.utils``: route helpers (GPS conversion, downsampling, interpolation)."""
