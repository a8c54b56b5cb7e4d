"""Command line interface (``hlaid --help``)."""

import os as _os
import signal as _signal
import sys as _sys
import threading as _threading


def _interrupted_early(signum, frame):  # Ctrl-C while the command line loads: one line, no traceback
    _sys.stderr.write("hlaid: interrupted\n")
    _sys.stderr.flush()
    _os._exit(130)


_early = _threading.current_thread() is _threading.main_thread() and \
    _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler
if _early:
    _signal.signal(_signal.SIGINT, _interrupted_early)
try:
    from .app import main
finally:
    if _early:
        _signal.signal(_signal.SIGINT, _signal.default_int_handler)

__all__ = ["main"]
