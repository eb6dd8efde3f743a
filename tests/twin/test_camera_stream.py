"""The wrist camera as a stream: frames of simulated instants, drawn in their own thread."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from busarm.errors import CameraError
from busarm.twin.arena_gen import random_arena
from busarm.twin.camera_stream import CameraStream
from busarm.twin.twin import Twin


@pytest.fixture(scope="module")
def twin() -> Iterator[Twin]:
    tw = Twin(arena=random_arena(5), realtime=False)
    yield tw
    tw.close()


def test_a_frame_shows_its_instant_not_the_drawing_time(twin: Twin) -> None:
    with CameraStream(twin, live=True) as stream:
        snap_at = twin.clock.now()
        expected = twin.render_camera(live=True, data=twin.snapshot())
        stream.capture()
        # The arm moves on while the frame may still be drawing.
        twin.data.qpos[twin.model.joint(twin.config.joints[0].name).qposadr[0]] += 0.5
        twin.mujoco.mj_forward(twin.model, twin.data)
        stream.drain()
        frame = stream.latest()
        assert frame is not None and frame.at_s == snap_at
        assert np.array_equal(frame.image, expected)
        assert not np.array_equal(frame.image, twin.render_camera(live=True))
        assert stream.latest() is None  # taken


def test_frames_queue_up_and_the_newest_is_kept(twin: Twin) -> None:
    with CameraStream(twin, live=True, backlog=2) as stream:
        times = []
        for _ in range(5):  # more than the backlog: captures wait for the drawing
            twin.step(0.1)
            times.append(twin.clock.now())
            stream.capture()
        stream.drain()
        assert stream.drawn == 5
        frame = stream.latest()
        assert frame is not None and frame.at_s == times[-1]


def test_a_failed_drawing_is_reported_to_the_capturer(twin: Twin) -> None:
    stream = CameraStream(twin, live=True)
    try:
        stream._todo.put((object(), 0.0))  # not a simulation state: the drawing fails
        with pytest.raises(CameraError, match="the camera stream stopped"):
            stream.drain()
        with pytest.raises(CameraError, match="the camera stream stopped"):
            stream.capture()
    finally:
        stream.close()
