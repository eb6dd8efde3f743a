"""The digital twin: a MuJoCo physics model of the arm, table, blocks and camera,
driven by the servo simulator through the same bytes as a real arm."""

__all__: list[str] = []
