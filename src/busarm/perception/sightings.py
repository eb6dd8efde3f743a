"""What ``BlockLocator`` reports: the blocks seen (``Sighting``), the things in a block's
colour that are not blocks (``NotBlock``), and both of a picture or pictures (``Found``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from busarm.perception.shape import Shape
from busarm.vision.color import Detection
from busarm.vision.localize import BlockLocation

__all__ = ["Found", "NotBlock", "Sighting"]


@dataclass(frozen=True)
class Sighting:
    """A block seen in a picture: colour, where it is, and whether the arm reaches it.

    ``reachable``: a grasp at the block's centre height is within the arm's reach and
    limits (any pitch); ``top_down``: straight down works too; ``reason`` says why not.
    ``whole``: False if the blob is cut by the picture's edge, or is split into blocks
    that do not explain its outline, so that its location is only rough (look again,
    facing it).
    """

    color: str
    location: BlockLocation
    detection: Detection | None
    reachable: bool
    top_down: bool
    reason: str = ""
    detections: tuple[Detection, ...] = field(default=(), repr=False)
    whole: bool = True
    shape: Shape | None = field(default=None, repr=False)
    """What its outline says it is (``busarm.perception.shape``; None: not judged, e.g.
    one of several touching blocks, or cut by the picture's edge)."""

    def to_dict(self) -> dict[str, object]:
        loc = self.location
        return {
            "color": self.color, "x_mm": round(loc.x_mm, 2), "y_mm": round(loc.y_mm, 2),
            "z_mm": round(loc.z_mm, 2), "yaw_deg": round(loc.yaw_deg, 2),
            "frames": loc.frames, "spread_max_mm": round(loc.spread_max_mm, 2),
            "reachable": self.reachable, "top_down": self.top_down, "reason": self.reason,
            "centroid_px": [round(v, 2) for v in loc.centroid_px], "whole": self.whole,
            "size_mm": round(loc.size_mm, 1),
            "shape": None if self.shape is None else self.shape.verdict,
        }


@dataclass(frozen=True)
class NotBlock:
    """A thing in a block's colour that its outline says is not a block (a cup, a pen)."""

    color: str
    shape: Shape
    detection: Detection | None = field(default=None, repr=False)

    @property
    def xy_mm(self) -> tuple[float, float]:
        return self.shape.xy_mm


@dataclass(frozen=True)
class Found:
    """What pictures show: the blocks (and things that may be: ``shape`` unsure), and the
    things in a block's colour that are not blocks."""

    blocks: list[Sighting]
    not_blocks: list[NotBlock]
