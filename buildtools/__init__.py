"""Build helpers shared by ``setup.py`` and the PEP 517 backend (not installed)."""
