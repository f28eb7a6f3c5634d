"""diracvi's on/off environment variables: ``1`` on, ``0`` or unset off, anything else an
error that names the variable, its value and what each setting does."""

from __future__ import annotations

import os


def env_switch(name: str, *, on: str, off: str) -> bool:
    """Whether the environment variable ``name`` is ``1``; ``on`` and ``off`` say what
    ``1`` and ``0`` / unset do, for the error raised on any other value."""
    value = os.environ.get(name, "").strip()
    if value in ("", "0"):
        return False
    if value == "1":
        return True
    raise ValueError(
        f"{name}={value!r} is not understood. Fix: set it to 1 ({on}) or 0 / unset ({off})."
    )
