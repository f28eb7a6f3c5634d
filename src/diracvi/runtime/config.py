"""Float64 for every computation.

Discrete Dirac integrators are judged at round-off (constraints ≤ 1e-12, interconnected
vs monolithic ≤ 1e-12), which single precision cannot reach. JAX defaults to float32, so
the package switches ``jax_enable_x64`` on when it is imported and every entry point
re-checks it (a user may switch it off again after importing us).
"""

import warnings

import jax

jax.config.update("jax_enable_x64", True)


def ensure_float64() -> None:
    """Switch float64 back on, loudly, if something turned it off after import."""
    if not jax.config.jax_enable_x64:
        warnings.warn(
            "JAX float64 mode (jax_enable_x64) was switched off after diracvi was imported; "
            "diracvi needs float64 for round-off-level constraints and is switching it back "
            "on. Arrays created while it was off are float32: recreate them.",
            RuntimeWarning,
            stacklevel=3,
        )
        jax.config.update("jax_enable_x64", True)
