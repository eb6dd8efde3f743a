"""Applications built on the arm, the vision layer and the twin: calibration flows,
localisation, pick-and-sort. Same code on the twin and on hardware."""

__all__: list[str] = []
