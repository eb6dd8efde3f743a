"""What the robot's sensors see, in the arm's and the floor's units: blocks located on
the table (``locate``: colour blobs from the wrist camera to table millimetres, touching
blocks split by their top faces, things that are not blocks found as obstacles) and the
floor seen from the wrist (``floor_view``). Pure: pictures, calibrations and joint angles
in, places out; the jobs (busarm.apps) decide what to do with them."""

__all__: list[str] = []
