"""busarm's version (also ``busarm.__version__``); a leaf, so that any layer may say it
without importing the package's public face."""

__all__ = ["__version__"]

__version__ = "0.1.0"
