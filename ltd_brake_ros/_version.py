"""The package's version, the one place it is written (``setup.py`` reads it; ``package.xml``
repeats it and a test keeps the two equal)."""

__version__ = "0.1.0"
