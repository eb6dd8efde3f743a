"""What only a simulated robot has, behind one handle: ``robot.sim`` (None on hardware).

Its truth (where the blocks and the base really are: for benchmarks, tests and reports,
never for the jobs), its world (the table's scene, the arena), and the cameras and
renderer housekeeping that people watching it need. The interfaces reach the twin only
through here; ``twin`` is the twin itself, for what this handle does not say.
"""

from __future__ import annotations

from busarm.base.odometry import Pose2D
from busarm.twin.arena import Arena
from busarm.twin.camera import TwinCamera
from busarm.twin.scene import Scene
from busarm.twin.twin import BlockState, Twin

__all__ = [
    "SimHandle",
]


class SimHandle:
    """The twin behind a ``Robot`` (see the module docstring)."""

    def __init__(self, twin: Twin) -> None:
        self.twin = twin

    def __repr__(self) -> str:
        world = f"arena {self.twin.arena.name!r}" if self.twin.arena is not None else (
            f"table {self.twin.scene.source!r}")
        return f"SimHandle({world})"

    @property
    def arena(self) -> Arena | None:
        """The mobile robot's arena, or None (an arm on a table)."""
        return self.twin.arena

    @property
    def scene(self) -> Scene:
        """What stands on the table (an arena twin's is empty)."""
        return self.twin.scene

    def blocks(self) -> list[BlockState]:
        """Where every block really is (mm, the arm's base frame): truth."""
        return self.twin.blocks()

    def base_pose(self) -> Pose2D | None:
        """Where the mobile base really is in its arena (m, rad), or None: truth."""
        mobile = self.twin.mobile
        return None if mobile is None else mobile.pose(self.twin.data)

    def base_velocity(self) -> tuple[float, float, float] | None:
        """How fast the mobile base really goes (m/s in the arena's x and y, rad/s), or
        None: truth."""
        mobile = self.twin.mobile
        return None if mobile is None else mobile.speed(self.twin.data)

    def wheel_targets_rev_s(self) -> tuple[float, ...] | None:
        """What the board last told each wheel motor (rev/s), or None without one: truth
        of what reached the wheels."""
        mobile = self.twin.mobile
        if mobile is None or mobile.board is None:
            return None
        return tuple(w.target_rev_s for w in mobile.board.wheels)

    def live_camera(self, view: str = "arm") -> TwinCamera:
        """A camera of the twin for a person to watch (``arm``: the wrist's, or
        ``overview``), drawn without shadows or antialiasing: several times cheaper on a
        CPU; what vision works on keeps them."""
        return TwinCamera(self.twin, view=view, live=True)

    def release_renderers(self) -> None:
        """Free the renderers this thread made (call as a thread that drew pictures ends)."""
        self.twin.release_renderers()
