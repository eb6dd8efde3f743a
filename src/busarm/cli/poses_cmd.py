"""``arm poses``: the named poses, the arm config's and those saved per robot.

``arm pose --save NAME`` keeps the measured joints under a name and ``arm move-joints
--pose NAME`` moves back (busarm.cli.arm_inputs has the robot's folder,
busarm.arm.named_poses keeps the file).
"""

from __future__ import annotations

import json

import click
from rich.table import Table

from busarm.arm.named_poses import delete_pose, list_poses, poses_file
from busarm.cli.common import ArmContext, pass_arm, robot_folder

__all__ = [
    "poses",
]


@click.command()
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@click.option("--delete", "delete_name", metavar="NAME", help="Forget the saved pose NAME.")
@pass_arm
def poses(ac: ArmContext, as_json: bool, delete_name: str | None) -> None:
    """The named poses (joint angles in deg): the arm config's, and the saved ones.

    Save the arm's present pose with `busarm arm pose --save NAME`; move to one with
    `busarm arm move-joints --pose NAME`. Saved poses are kept per robot (per --port) in
    $XDG_CONFIG_HOME/busarm/ROBOT/poses.json. No bus needed.
    """
    folder = robot_folder(ac.settings.robot_key())
    if delete_name is not None:
        delete_pose(folder, ac.config, delete_name)
        ac.settings.err.print(f"deleted pose {delete_name!r} from {poses_file(folder)}",
                              highlight=False, markup=False, soft_wrap=True)
    names = [j.name for j in ac.config.joints]
    found = list_poses(folder, ac.config)
    if as_json:
        click.echo(json.dumps({"file": str(poses_file(folder)), "poses": [
            {"name": p.name, "builtin": p.builtin,
             "joints_deg": {n: round(a, 3) for n, a in zip(names, p.joints_deg, strict=True)}}
            for p in found]}))
        return
    table = Table(title=f"poses of the {ac.config.name}, joint angles in deg",
                  caption=f"saved poses: {poses_file(folder)}", title_justify="left",
                  caption_justify="left")
    table.add_column("name")
    table.add_column("from")
    for n in names:  # "base_yaw" in two lines: five columns fit 80 characters
        table.add_column(n.replace("_", "\n"), justify="right")
    for p in found:
        table.add_row(p.name, "arm config" if p.builtin else "saved",
                      *(f"{a + 0.0:.1f}" for a in p.joints_deg))
    ac.settings.out.print(table)
