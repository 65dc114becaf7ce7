"""The installed version of cwproc (the foundation layer: imports nothing of cwproc)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("cwproc")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.1.0+unknown"
