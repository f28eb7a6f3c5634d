"""RLC tolerance study with ``dv.sweep``: how long the circuit rings, over R and C.

The paper's parallel RLC circuit (R = 1, l = 0.75, C = 3; h = 0.1, 400 steps) with the
resistor and the capacitor each off by up to ±20 % (a 24 × 24 grid), and a Monte Carlo
sample of 1000 circuits whose parts are 5 % parts (normal, σ = 5 %). The figure shows the
energy's 1/e decay time over the grid — for this circuit close to the RC time
constant — and the spread it has over the Monte Carlo sample.

    python examples/sweep_rlc_tolerance.py [FIGURE.png] [--scheduler tcp://HOST:8786]

Runs in well under a minute on a laptop core (embedded: no Dask needed).
"""

# gallery: RLC tolerance study (dv.sweep)

from __future__ import annotations

import argparse
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import diracvi as dv
from diracvi import problems

R0, C0 = 1.0, 3.0
DT, STEPS = 0.1, 400


def decay_time(ds):
    """The first time the energy falls below E(0)/e, linearly interpolated (NaN if never)."""
    energy = ds["energy"]
    e0 = energy.isel(step=0)
    below = energy < e0 / np.e
    k = below.argmax("step")  # the first step below
    t = ds["step_time"].values
    e = energy.values
    k_ = k.values
    before = np.take_along_axis(e, np.maximum(k_ - 1, 0)[..., None], axis=-1)[..., 0]
    after = np.take_along_axis(e, k_[..., None], axis=-1)[..., 0]
    target = e0.values / np.e
    frac = (before - target) / np.where(before > after, before - after, 1.0)
    out = t[np.maximum(k_ - 1, 0)] + frac * DT
    return np.where(below.any("step").values, out, np.nan)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default="sweep_rlc_tolerance.png")
    parser.add_argument("--scheduler", default=None, help="a Dask scheduler address")
    args = parser.parse_args()
    client = None
    if args.scheduler:
        from distributed import Client

        client = Client(args.scheduler)

    start = time.perf_counter()
    grid = {"R": R0 * np.linspace(0.8, 1.2, 24), "C": C0 * np.linspace(0.8, 1.2, 24)}
    ds = dv.sweep(problems.build_rlc, grid, dt=DT, steps=STEPS, client=client)
    rng = np.random.default_rng(2026)
    parts = {"R": R0 * (1 + 0.05 * rng.standard_normal(1000))}
    parts["C"] = C0 * (1 + 0.05 * rng.standard_normal(1000))
    mc = dv.sweep(problems.build_rlc, samples=parts, dt=DT, steps=STEPS, client=client)
    elapsed = time.perf_counter() - start
    assert (ds.status == 0).all() and (mc.status == 0).all()

    tau = decay_time(ds)
    tau_mc = decay_time(mc)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    mesh = left.pcolormesh(ds.C, ds.R, tau, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=left, label="energy 1/e decay time")
    lines = left.contour(ds.C, ds.R, tau, colors="white", linewidths=0.7)
    left.clabel(lines, fontsize=7)
    left.plot([C0], [R0], "r+", markersize=12)
    # labelled beside the marker: a legend box would hide part of the map (data everywhere)
    left.annotate("nominal R = 1, C = 3", (C0, R0), xytext=(8, -12),
                  textcoords="offset points", color="white", fontsize=8)  # fmt: skip
    left.set(xlabel="C", ylabel="R", title=f"{ds.R.size} × {ds.C.size} grid, ±20 % parts")
    right.hist(tau_mc, bins=40, color="tab:blue", alpha=0.8)
    lo, hi = np.percentile(tau_mc, [2.5, 97.5])
    for x in (lo, hi):
        right.axvline(x, color="k", linestyle="--", linewidth=0.8)
    right.set(
        xlabel="energy 1/e decay time",
        ylabel="circuits",
        title=f"{mc.sizes['sample']} circuits with 5 % parts: 95 % in [{lo:.2f}, {hi:.2f}]",
    )
    fig.suptitle(
        f"dv.sweep: {ds.R.size * ds.C.size + mc.sizes['sample']} RLC circuits × {STEPS} steps",
        fontsize=10,
    )
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}: {elapsed:.1f} s of sweeping; nominal decay time {tau[11, 11]:.3f}")


if __name__ == "__main__":
    main()
