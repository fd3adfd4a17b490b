"""The package's version (read by the build backend and by the bench's result files)."""

__version__ = "0.1.0"
