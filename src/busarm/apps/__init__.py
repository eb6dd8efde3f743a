"""The jobs, one folder each, built on the robot (busarm.robot): ``pick_sort`` (the arm
sorting a table), ``navigation`` (mapping and driving on the mobile base), ``transport``
(fetching and delivering a block between named points), ``line_follow`` (a lap of the
taped loop). The same code runs on the twin and on hardware."""

__all__: list[str] = []
