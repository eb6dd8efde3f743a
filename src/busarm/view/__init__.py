"""The robot live in Foxglove, and recorded for it: ``busarm view`` and ``busarm record``.

``RobotView`` (busarm.view.live) logs the robot's channels (its URDF, the joints as
transforms, the camera, the Lidar, a job's map, plan and blocks found) with Foxglove's
well-known schemas; ``serve_view`` (busarm.view.server) serves them over Foxglove's
WebSocket protocol, and ``McapRecording`` (busarm.view.recording) writes them into an
MCAP file Foxglove replays. Needs the ``busarm[view]`` extra (foxglove-sdk).
"""

__all__: list[str] = []
