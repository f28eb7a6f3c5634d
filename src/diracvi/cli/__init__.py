"""The ``diracvi`` command line (typer): ``diracvi.cli:app`` is the console script."""

from .main import EXIT_FAILURE, EXIT_USAGE, app

__all__ = ["EXIT_FAILURE", "EXIT_USAGE", "app"]
