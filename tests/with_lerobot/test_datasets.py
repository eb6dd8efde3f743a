"""busarm's episodes as LeRobotDatasets, loaded back by LeRobot's own ``LeRobotDataset``:
the declared features (dtype, shape, names), every frame's values, the episode
boundaries and their tasks intact, the folder taking its name only when finished; and
``record_expert``'s report agreeing with what was written (episodes kept, frames, the
expert's success on the twin's truth)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from lerobot.datasets.lerobot_dataset import LeRobotDataset

from busarm.cli.main import cli
from busarm.errors import ConfigError
from busarm.learn.dataset import DatasetWriter
from busarm.learn.expert import EpisodeTask, run_expert
from busarm.learn.features import DEFAULT_FPS, TASK_STATE_NAMES, Features, motor_names
from busarm.learn.record import record_expert
from busarm.twin.spec import TwinSpec

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]


def test_expert_episodes_load_in_lerobot_intact(twin_calibration: tuple[Path, Path],
                                                tmp_path: Path) -> None:
    episodes = [run_expert(EpisodeTask(i, "one-block", seed, DEFAULT_FPS, *twin_calibration))
                for i, seed in enumerate((11, 12, 13))]
    assert all(e.success for e in episodes)
    config = TwinSpec().arm_config()
    root = tmp_path / "ds"
    with DatasetWriter(root, Features.of(config)) as writer:
        for e in episodes:
            writer.add(e.text, e.states, e.actions, task_state=e.task_state,
                       success=e.success)
    assert not root.with_name("ds.part").exists()  # finished: under its own name
    with pytest.raises(ConfigError, match="exists"):
        DatasetWriter(root, Features.of(config))
    with DatasetWriter(tmp_path / "empty", Features.of(config)) as empty:
        assert empty.part.is_dir() and not empty.root.exists()
    assert not empty.part.exists() and not empty.root.exists()  # nothing in it: no trace

    ds = LeRobotDataset("local/busarm", root=root)
    names = motor_names(config)
    assert ds.fps == DEFAULT_FPS and ds.meta.robot_type == "busarm"
    for key, shape, want in (("observation.state", (6,), names), ("action", (6,), names),
                             ("observation.environment_state", (5,),
                              list(TASK_STATE_NAMES))):
        feature = ds.meta.features[key]
        assert feature["dtype"] == "float32" and tuple(feature["shape"]) == shape
        assert feature["names"] == want
    assert ds.num_episodes == 3 and ds.num_frames == sum(e.frames for e in episodes)
    start = 0
    for k, e in enumerate(episodes):
        meta = ds.meta.episodes[k]
        assert (meta["dataset_from_index"], meta["dataset_to_index"]) == (start,
                                                                          start + e.frames)
        assert meta["tasks"] == [e.text]
        for i in (0, e.frames // 2, e.frames - 1):
            frame = ds[start + i]
            assert int(frame["episode_index"]) == k and int(frame["frame_index"]) == i
            assert frame["task"] == e.text
            assert np.array_equal(frame["observation.state"].numpy(), e.states[i])
            assert np.array_equal(frame["action"].numpy(), e.actions[i])
            assert np.array_equal(frame["observation.environment_state"].numpy(),
                                  e.task_state)
            assert bool(frame["next.success"]) is (i == e.frames - 1)
        start += e.frames


def test_record_expert_reports_what_it_wrote(tmp_path: Path) -> None:
    report = record_expert(tmp_path / "ds", episodes=4, seed=20, workers=2)
    ds = LeRobotDataset("local/busarm", root=tmp_path / "ds")
    assert report.episodes == 4 and report.workers == 2
    assert report.kept == ds.num_episodes == report.successes
    assert report.frames == ds.num_frames and report.episodes_per_hour > 0
    assert f"{report.successes}/4" in report.text()
    tasks = {ds.meta.episodes[k]["tasks"][0] for k in range(ds.num_episodes)}
    assert all(t.startswith("put the ") and t.endswith(" bin") for t in tasks)
    with pytest.raises(ConfigError, match="seed"):
        record_expert(tmp_path / "held-out", episodes=2, seed=999_999)


def test_a_recording_that_cannot_start_leaves_nothing(tmp_path: Path) -> None:
    runner = CliRunner(mix_stderr=False)
    out = tmp_path / "keys"
    result = runner.invoke(cli, ["record", str(out), "--teleop", "keyboard"])  # no terminal
    assert result.exit_code == 2 and "terminal" in result.stderr
    assert list(tmp_path.iterdir()) == []
    both = runner.invoke(cli, ["record", str(out), "--expert", "pick-sort", "--leader", "sim"])
    assert both.exit_code == 2 and "give one of" in both.stderr
    assert list(tmp_path.iterdir()) == []
