"""Where a thing found not to be a block is (busarm.apps.pick_sort.table_view): on its
own footprint (a disc's circle, a bar's rectangle), so that a block set down beside a
long bar is not taken for part of it and left on the table."""

from __future__ import annotations

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlanner
from busarm.apps.pick_sort.restage import staging_spot
from busarm.apps.pick_sort.table_view import SAME_BLOCK_MM, _on_thing, thing_footprint
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.perception.measure import BoxFit, CylinderFit
from busarm.perception.shape import Shape


def _shape(box: BoxFit, cylinder: CylinderFit | None = None) -> Shape:
    return Shape("not a block", "a test thing", box.width_mm, box, box, (), False, cylinder)


def test_a_block_beside_a_long_bar_is_not_on_it() -> None:
    # As in the look-alike family's seed 11: a blue bar 132 x 19 mm at (155, -60), a blue
    # block set down 58 mm from its middle beside it. The bar's circle (66 mm) covered the
    # block: it was dropped from every look as "where the bar is" and never sorted.
    bar = _shape(BoxFit(155.0, -60.0, -45.0, 132.0, 19.0, 19.0, 0.3, 1))
    assert not _on_thing(bar, (109.0, -96.0))
    for along in (-60.0, 0.0, 60.0):  # on it: anywhere along it
        assert _on_thing(bar, (155.0 + along * 0.7071, -60.0 - along * 0.7071))
    assert not _on_thing(bar, (155.0 + 80.0 * 0.7071, -60.0 - 80.0 * 0.7071))  # past its end
    # Seen again a few mm off, a small thing is still itself.
    dot = _shape(BoxFit(0.0, 0.0, 0.0, 10.0, 10.0, 60.0, 0.3, 1))
    assert _on_thing(dot, (SAME_BLOCK_MM - 1.0, 0.0))
    assert not _on_thing(dot, (SAME_BLOCK_MM + 1.0, 0.0))


def test_a_round_thing_covers_its_circle() -> None:
    disc = _shape(BoxFit(0.0, 0.0, 0.0, 50.0, 50.0, 4.0, 2.0, 1),
                  CylinderFit(5.0, 0.0, 60.0, 4.0, 0.2))
    assert _on_thing(disc, (5.0, 29.0)) and not _on_thing(disc, (5.0, 31.0))


def test_a_block_set_down_to_be_taken_again_keeps_off_a_thing_found_before() -> None:
    # The lookalike bench's seed 38: a large blue cube taken tilted was set down 2 mm from
    # a blue cup found earlier (the last picture did not show the cup): its blob and the
    # cup's made one, it was never seen whole again and was left on the table.
    bar = thing_footprint(_shape(BoxFit(155.0, -60.0, -45.0, 132.0, 19.0, 19.0, 0.3, 1)))
    assert bar.overlaps(Footprint.square(155.0 + 60 * 0.7071, -60.0 - 60 * 0.7071, 2.0, 0.0))
    assert not bar.overlaps(Footprint.square(155.0 + 20.0, -60.0 + 20.0, 2.0, 0.0))
    planner = GraspPlanner(ArmKinematics.from_config(load_arm_config()), 0.0, 40.0, 60.0, 75.0)
    gaps, room = [60.0, 53.0, 46.0], 40.0 + 2 * (10.0 + 10.0)
    free = staging_spot(planner, [], [], [], gaps, room)
    assert free is not None
    x, y = free[0] + 38.0, free[1]  # a cup 34 mm across, its rim 21 mm from the block's middle
    cup = _shape(BoxFit(x, y, 0.0, 30.0, 30.0, 58.7, 1.04, 1), CylinderFit(x, y, 34.1, 58.7, 0.2))
    where = thing_footprint(cup)
    assert where.overlaps(Footprint.square(x + 16.0, y, 2.0, 0.0))  # its rim
    assert not where.overlaps(Footprint.square(x + 19.0, y, 2.0, 0.0))
    spot = staging_spot(planner, [], [where], [], gaps, room)
    assert spot is not None and spot != free
    assert not Footprint.square(*spot, room, 0.0).overlaps(where), spot
