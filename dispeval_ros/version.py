"""The project's version (one place: the package, setup.py and provenance records read it)."""

__version__ = "0.1.0"
