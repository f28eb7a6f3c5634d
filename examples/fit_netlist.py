"""Fit a SPICE netlist's parameters to a measured waveform, with gradients through the run.

Run: python examples/fit_netlist.py   (about 20 s of CPU)

A half-wave rectifier with a smoothing capacitor is written as an ordinary netlist whose
load resistance and diode saturation current are ``.param`` values (the capacitance is
known: from the output voltage alone only the ratios of ``I_S``, ``C`` and ``1/R`` are
identifiable, since ``C dv/dt = I_S e^{v_D/nV_T} − v/R`` is homogeneous in the three).
Its output voltage, sampled with noise (σ = 5 mV), is the "measurement". The two values
are then fitted by Levenberg–Marquardt (``optimistix.least_squares``) in log space through
``spice.run`` itself: ``spice.run(NETLIST, dt=..., params=...)`` accepts traced values, so the
residuals' Jacobian comes from forward-mode derivatives of the run (implicit-function
derivatives of each Newton step). The fit recovers each value within three standard
errors, ``cov = σ² (JᵀJ)⁻¹``.
"""

# gallery: Fitting a netlist's parameters (gradients through spice.run)

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from diracvi import spice

NETLIST = """Half-wave rectifier with a smoothing capacitor
.param rload=1k isat=1e-14
V1 in 0 SIN(0 5 500)
D1 in out dm
C1 out 0 10u
R1 out 0 {rload}
.model dm D(IS={isat} N=1.2)
.tran 20u 3m uic
.end
"""
NAMES = ("rload", "isat")
TRUE = np.array([1e3, 1e-14])
SIGMA = 5e-3


def observe(log_theta):
    """The output voltage at every step (t > 0) for parameters ``exp(log_theta)``."""
    values = dict(zip(NAMES, jnp.exp(log_theta), strict=True))
    return spice.run(NETLIST, dt=20e-6, params=values)["v(out)"][1:]  # a fixed step: traced


def fit(seed: int = 0):
    """``(estimate, standard errors, data, fitted)`` from a start 50–60 % off."""
    rng = np.random.default_rng(seed)
    clean = np.asarray(observe(jnp.log(TRUE)))
    data = clean + SIGMA * rng.standard_normal(clean.shape)
    start = jnp.log(TRUE * np.array([1.5, 0.4]))

    def residuals(log_theta, _):
        return (observe(log_theta) - data) / SIGMA

    solver = optx.LevenbergMarquardt(rtol=1e-8, atol=1e-8)
    solution = optx.least_squares(residuals, solver, start, options={"jac": "fwd"}, max_steps=50)
    log_theta = solution.value
    jac = np.asarray(jax.jacfwd(residuals)(log_theta, None))  # of r/σ: cov = (JᵀJ)⁻¹
    errors = np.exp(np.asarray(log_theta)) * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))
    return np.exp(np.asarray(log_theta)), errors, data, np.asarray(observe(log_theta))


def main(out="fit_netlist.png"):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    estimate, errors, data, fitted = fit()
    for name, true, value, error in zip(NAMES, TRUE, estimate, errors, strict=True):
        print(f"{name:6s} true {true:.4g}  fitted {value:.4g} ± {error:.2g}")
    print(f"residual rms / σ = {np.std(data - fitted) / SIGMA:.3f}")
    t_ms = 20e-3 * np.arange(1, len(data) + 1)  # the fixed 20 µs step, in ms
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(t_ms, data, ".", ms=3, alpha=0.5, label="v(out), noisy data")
    ax.plot(t_ms, fitted, "-", label="v(out), fit")
    ax.set_xlabel("t (ms)")
    ax.set_ylabel("v(out) (V)")
    ax.set_title(
        "Netlist fit: "
        + ", ".join(
            f"{n} = {e:.4g} ± {s:.2g} {u}"
            for n, u, e, s in zip(NAMES, ("Ω", "A"), estimate, errors, strict=True)
        )
    )
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
