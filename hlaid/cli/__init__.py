"""Command line interface (``hlaid --help``)."""

from .app import main

__all__ = ["main"]
