"""Exceptions that carry a one-line message for the user.

Library code raises :class:`InputError` (a ``ValueError``) for anything the user can fix:
a malformed file, an out-of-range parameter, an unknown config key. The command line turns
it into a single line on stderr and exit status 2; anything else is an internal error
(exit status 1).
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input. ``str(err)`` is one line naming the file or field and what is wrong."""

    def __init__(self, message: str, *, source: str | None = None):
        message = " ".join(str(message).split())  # always one line
        self.source = source
        super().__init__(f"{source}: {message}" if source else message)


class ConfigError(InputError):
    """A configuration file that does not match its schema."""


class NotIdentifiableError(InputError):
    """The record does not hold enough information to identify what was asked."""
