"""The package's version (its own module, so any floor can read it)."""

__version__ = "0.1.0"
