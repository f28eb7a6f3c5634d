"""diracvi's on/off environment variables: ``1`` on, ``0`` or unset off, anything else an
error that names the variable, its value and what each setting does."""

from __future__ import annotations

import os


def env_switch(name: str, *, on: str, off: str, default: bool = False) -> bool:
    """Whether the environment variable ``name`` is ``1`` (unset: ``default``); ``on``
    and ``off`` say what ``1`` and ``0`` do, for the error raised on any other value."""
    value = os.environ.get(name, "").strip()
    if value == "":
        return default
    if value in ("0", "1"):
        return value == "1"
    one, zero = ("1 / unset", "0") if default else ("1", "0 / unset")
    raise ValueError(
        f"{name}={value!r} is not understood. Fix: set it to {one} ({on}) or {zero} ({off})."
    )
