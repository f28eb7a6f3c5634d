"""Discretization: the quadrature rules and the discrete maps they define on a system
(discrete momenta, constraint rows, reactions, the step residuals)."""
