"""Vision: camera sources, colour and AprilTag detection, camera calibration, and
pixel to table coordinates in millimetres.

Imports numpy and OpenCV; never the bus, the simulator, the arm or the twin (the
twin's camera is reached through the ``twin`` camera scheme, imported lazily by name).
Modules are imported directly: ``busarm.vision.color``, ``busarm.vision.calibration``...
"""

__all__: list[str] = []
