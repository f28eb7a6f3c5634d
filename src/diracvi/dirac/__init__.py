r"""Dirac structures as objects to compute with (paper §2.1–2.3 and §4.2).

Continuous, at a point ``(q, p)`` of ``T*Q``: :class:`DiracStructure` (a subspace of
``V ⊕ V*``, ``V = T_{(q,p)}T*Q``) with :func:`induced` ``D_Δ``, :func:`interaction`
``D_int``, :func:`direct_sum` ``⊕``, :func:`tensor` ``⊠`` and :func:`interconnection`.

Discrete: the Tulczyjew maps (:func:`kappa_d`, :func:`omega_flat_plus`,
:func:`omega_flat_minus`), the discrete Dirac differentials 𝔇^±L_d, and
:class:`DiscreteDiracStructure` (``D^{d±}_Δ``, ``D^{d+}_int``, ``⊕``, ``⊠_d``).

Diagnostic: :func:`trajectory_residual` checks ``(X_d^k, 𝔇^±L_d) ∈ D^{d±}_Δ`` step by
step for any ``DiracSystem`` (also ``Trajectory.dirac_residual``).

See ``docs/dirac-structures.md`` for the map to the paper's notation.
"""

from ._diagnostic import StepResiduals, step_residuals, trajectory_residual
from ._discrete import (
    DirectSumDiscrete,
    DiscreteDiracStructure,
    InducedDiscrete,
    InteractionDiscrete,
    TensorDiscrete,
)
from ._forms import RedundantFormsWarning, check_regular, is_clean
from ._structure import (
    DiracStructure,
    direct_sum,
    induced,
    interaction,
    interconnection,
    pairing_matrix,
    tensor,
)
from ._tulczyjew import (
    dirac_differential_minus,
    dirac_differential_plus,
    gamma_d_minus,
    gamma_d_plus,
    kappa_d,
    kappa_d_inverse,
    omega_flat_minus,
    omega_flat_plus,
    system_dirac_differential,
)

__all__ = [
    "DiracStructure",
    "DirectSumDiscrete",
    "DiscreteDiracStructure",
    "InducedDiscrete",
    "InteractionDiscrete",
    "RedundantFormsWarning",
    "StepResiduals",
    "TensorDiscrete",
    "check_regular",
    "dirac_differential_minus",
    "dirac_differential_plus",
    "direct_sum",
    "gamma_d_minus",
    "gamma_d_plus",
    "induced",
    "interaction",
    "interconnection",
    "is_clean",
    "kappa_d",
    "kappa_d_inverse",
    "omega_flat_minus",
    "omega_flat_plus",
    "pairing_matrix",
    "step_residuals",
    "system_dirac_differential",
    "tensor",
    "trajectory_residual",
]
