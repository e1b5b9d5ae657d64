"""Command-line programs; each ``soilstats/<name>.py`` shim runs one with ``python -m``."""
