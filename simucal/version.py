"""simucal's version, in one place: the package's face (simucal.__version__), pyproject.toml's and the cache's
key of a derived user model (fit/catalog.py) read it here."""
__version__ = "0.1.0"
