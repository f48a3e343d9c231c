"""``srunner.scenariomanager``: the data provider and the game clock, backed by the running route."""
