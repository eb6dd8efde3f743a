"""The ``busarm`` command line: the only layer that parses argv or prints.

``main`` holds the group, the global options and the error handling; each other
module adds a few commands (``bus_cmds``, ``servo_cmds``, ``config_cmds``,
``proto_cmds``, ``sim_cmds``, ``demo``).
"""

__all__: list[str] = []
