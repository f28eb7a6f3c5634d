"""Shared by the gallery examples: where to write the figure, and a quiet matplotlib."""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")


def figure_path(default: str) -> Path:
    """The figure's path: the first command-line argument, else ``default`` in the cwd."""
    return Path(sys.argv[1] if len(sys.argv) > 1 else default)
