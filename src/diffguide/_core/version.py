"""The package version, defined once (re-exported as ``diffguide.__version__``; read by the
build backend for the distribution's version, and hashed into the caches' fingerprints)."""

__version__ = "0.2.0"
