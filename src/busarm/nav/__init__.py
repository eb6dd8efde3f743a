"""Navigation: occupancy grids and their map files (pure numpy, no robot I/O)."""

__all__: list[str] = []
