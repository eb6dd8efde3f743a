"""``robot.sim``: what only a simulated robot has, behind one handle (issue 29)."""

from __future__ import annotations

from busarm import BoardSettings, CameraSpec, Robot, RobotConfig, SimSpec, TwinSpec

NO_CALIBRATION = CameraSpec(calibrate=False)


def test_a_robot_on_servos_alone_has_no_sim_handle() -> None:
    with Robot.open(RobotConfig(SimSpec(), camera=NO_CALIBRATION)) as robot:
        assert robot.sim is None and robot.twin is None


def test_the_handle_gives_the_table_truth_and_a_live_camera() -> None:
    with Robot.open(RobotConfig(TwinSpec(seed=4, blocks=3), camera=NO_CALIBRATION)) as robot:
        sim = robot.sim
        assert sim is not None and sim.twin is robot.twin
        assert sim.arena is None and sim.base_pose() is None
        blocks = sim.blocks()
        assert [b.color for b in blocks] == [b.color for b in sim.scene.blocks]
        assert all(b.z_mm > 0 for b in blocks)
        frame = sim.live_camera("overview").read()
        assert frame.image.shape[2] == 3 and frame.image.mean() > 10  # a picture, not black
        sim.release_renderers()
        assert repr(sim).startswith("SimHandle(table ") and len(repr(sim)) < 120


def test_the_base_truth_follows_the_wheels() -> None:
    world = TwinSpec(family="arena", seed=2, slip=False, controller=BoardSettings())
    with Robot.open(RobotConfig(world, camera=NO_CALIBRATION)) as robot:
        sim, base = robot.sim, robot.base
        assert sim is not None and base is not None and sim.arena is not None
        before = sim.base_pose()
        assert before is not None
        base.move_by(0.3, 0.0, 0.0)
        after = sim.base_pose()
        assert after is not None
        moved = after.relative_to(before)
        assert abs(moved.x_m - 0.3) < 0.03 and abs(moved.y_m) < 0.03
