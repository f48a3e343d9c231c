"""Baselines trained on b2d-data clips and scored closed loop: AD-MLP, a TCP-style model, a route follower."""
