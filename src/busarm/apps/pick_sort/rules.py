"""Sorting rules: which place each block goes to.

- ``color`` (the default): the bin named as its colour (``red=...``);
- ``size``: the bin named as its size class (``small``, ``medium``, ``large``:
  ``busarm.perception.size_classes``), its side measured from the picture;
- ``tag``: by the AprilTag (36h11) on its top, read from a close look: ``tag_places``
  maps ids to places (``0,1=left;2=right``); without it tag ``i`` goes to the ``i``-th
  place (counting round the places, in the order the bins are given).

A place is a bin by its name; its position comes from the robot (a twin's trays) or
``--bins NAME=X,Y;...``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from busarm.errors import ConfigError
from busarm.perception.size_classes import SIZE_CLASSES_MM, size_class
from busarm.units import check_int_range, listing
from busarm.vision.tags import TAG_COUNT

__all__ = [
    "SORT_BY",
    "SortRule",
    "parse_tag_places",
]


SORT_BY = ("color", "size", "tag")

Bins = Mapping[str, tuple[float, float]]


@dataclass(frozen=True)
class SortRule:
    """Sort ``by`` colour, size class or tag id (``SORT_BY``); ``tag_places``: tag id ->
    place name (by tag only; empty: round the places)."""

    by: str = "color"
    tag_places: Mapping[int, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.by not in SORT_BY:
            raise ConfigError(f"sort by {self.by!r}; allowed: {', '.join(SORT_BY)}")
        if self.tag_places and self.by != "tag":
            raise ConfigError(f"tag places are for sorting by tag, not by {self.by}")
        for tag in self.tag_places:
            check_int_range("tag id", tag, 0, TAG_COUNT - 1)

    def __repr__(self) -> str:
        places = "".join(f", {t}->{p}" for t, p in sorted(self.tag_places.items()))
        return f"SortRule({self.by}{places})"

    @property
    def reads_tags(self) -> bool:
        """Whether each block's tag must be read before its place is known."""
        return self.by == "tag"

    def places(self, bins: Bins, colors: Sequence[str]) -> dict[str, tuple[float, float]]:
        """The bins of ``bins`` this rule sorts into (``colors``: the colours to sort);
        ConfigError, naming what it needs, if there is none."""
        if self.by == "color":
            out = {c: bins[c] for c in colors if c in bins}
            needs = f"a bin for a colour to sort ({listing(colors) or 'none'})"
        elif self.by == "size":
            out = {n: bins[n] for n in SIZE_CLASSES_MM if n in bins}
            needs = f"a bin named as a size class ({listing(SIZE_CLASSES_MM)})"
        else:
            wanted = set(self.tag_places.values())
            unknown = sorted(wanted - set(bins))
            if unknown:
                raise ConfigError(f"tag places {listing(unknown)}: no such bin (bins: "
                                  f"{listing(bins) or 'none'})")
            out = {n: xy for n, xy in bins.items() if not wanted or n in wanted}
            needs = "a bin for the tags to go to"
        if not out:
            raise ConfigError(f"sorting by {self.by} needs {needs}; bins given: "
                              f"{listing(bins) or 'none'} (--bins NAME=X,Y;...)")
        return out

    def place_for(self, color: str, size_mm: float, tag_id: int | None,
                  places: Sequence[str]) -> str | None:
        """The place a block of ``color``, ``size_mm`` wide, tagged ``tag_id`` goes to,
        among ``places`` (None: by tag, its tag not read or mapped to no place)."""
        if self.by == "color":
            return color
        if self.by == "size":
            return size_class(size_mm)
        if tag_id is None:
            return None
        if self.tag_places:
            return self.tag_places.get(tag_id)
        return places[tag_id % len(places)] if places else None

    def what(self, color: str, size_mm: float, tag_id: int | None) -> str:
        """What the rule sorts this block as, in words (``red``, ``large``, ``tag 3``)."""
        if self.by == "color":
            return color
        if self.by == "size":
            return f"{size_class(size_mm)} ({size_mm:.0f} mm)"
        return "an unread tag" if tag_id is None else f"tag {tag_id}"


def parse_tag_places(text: str) -> dict[int, str]:
    """``0,1=left;2-4=right`` -> {0: 'left', 1: 'left', 2: 'right', 3: 'right', 4:
    'right'}; ConfigError naming the bad part."""
    out: dict[int, str] = {}
    for part in (p.strip() for p in text.split(";")):
        if not part:
            continue
        ids_text, sep, place = part.partition("=")
        if not sep or not place.strip() or not ids_text.strip():
            raise ConfigError(f"tag places {part!r}: expected IDS=PLACE, e.g. 0,1=left or "
                              "2-4=right")
        for item in ids_text.split(","):
            lo, dash, hi = item.strip().partition("-")
            try:
                first, last = int(lo), int(hi if dash else lo)
            except ValueError:
                raise ConfigError(f"tag places {part!r}: {item.strip()!r} is not a tag id "
                                  f"or a range of them (0..{TAG_COUNT - 1})") from None
            for tag in range(check_int_range("tag id", first, 0, TAG_COUNT - 1),
                             check_int_range("tag id", last, 0, TAG_COUNT - 1) + 1):
                if tag in out and out[tag] != place.strip():
                    raise ConfigError(f"tag places: tag {tag} goes to both {out[tag]} and "
                                      f"{place.strip()}")
                out[tag] = place.strip()
    if not out:
        raise ConfigError("tag places are empty: expected IDS=PLACE;..., e.g. 0,1=left")
    return out
