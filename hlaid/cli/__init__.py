"""Command line interface (``hlaid --help``)."""

from .main import main

__all__ = ["main"]
