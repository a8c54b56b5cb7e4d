"""The installed version of hlaid (``hlaid.__version__``), for the modules that record it."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("hlaid")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0.0.0+unknown"
