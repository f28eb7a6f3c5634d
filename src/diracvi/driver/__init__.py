"""The driver: one plan per run (solver choice, solvability and initial-data checks), the
stepping loop, traced runs, recording, checkpoints, ensembles and the trajectory."""
