"""Models: Lagrange–Dirac systems, their interconnection, packing of alike subsystems,
callable signatures, consistency of initial data and model files. Knows no rule, solver
or driver."""
