"""The benchmarks: one module per benchmark, run by ``busarm bench ...`` (``busarm.cli``).

Speed targets are checked here, never by timed unit tests. Results, with the machine
they ran on, go to ``docs/benchmarks.md``. Every run function returns a dataclass whose
``to_dict()`` is the ``--json`` output.

- ``bus`` -- ``busarm bench [--port P] [--json]`` (``make bench``): position reads, the
  full-arm state loop and an ID scan, each beside the wire limit from the same baud rate
  and turnaround. With the default port ``sim`` the simulated arm runs in its own process
  on a pty.
- ``peers`` (with ``peer_clients``, ``peers_report``) -- ``python -m busarm.bench.peers``
  (``make bench-peers``): the same simulator driven by busarm, pylx16a and
  lewansoul-lx16a side by side (read rate, and what each does after a stray byte or a
  late reply). The peers are installed only for this run (the ``peers`` extra).
- ``ik`` -- ``busarm bench ik``: accuracy and speed of the closed-form arm IK;
  ``ik_peers`` -- with ``--peers`` (``make bench-ik``), Robotics Toolbox and ikpy on the
  same targets; ``python -m busarm.bench.ik_peers`` adds the ``robot.ik_LM`` caveat check.
- ``vision`` -- ``busarm bench vision``: colour detection beside the vendor-style
  pipeline, and detect + localise, on one core; ``synthetic`` renders test scenes.
- ``locate`` -- ``busarm bench locate``: localisation accuracy against the twin's truth.
- ``pick`` -- ``busarm bench pick``: pick-and-sort over seeded twin scenes.
- ``common`` -- what they share: machine info, latency percentiles, the progress
  callback, the twin calibration summary.
"""

__all__: list[str] = []
