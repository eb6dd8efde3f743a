"""Camera sources: image folders, video files, USB cameras (a stand-in VideoCapture), the
scheme registry of ``open_camera``, and the image check shared by the vision layer."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, ClassVar

import cv2
import numpy as np
import pytest

import busarm.vision.camera as camera_mod
from busarm.errors import CameraError, ConfigError
from busarm.vision.camera import (
    CAMERA_SCHEMES,
    CameraBase,
    CameraFrame,
    CameraSource,
    EndOfFrames,
    ImageFolderSource,
    UsbCamera,
    VideoFileSource,
    check_bgr_image,
    open_camera,
)

W, H = 64, 48


def numbered(value: int, w: int = W, h: int = H) -> np.ndarray:
    """A frame whose pixels all carry ``value`` (so the order can be read back)."""
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = (value, 255 - value, 7)
    return img


def write_images(folder: Path, names: list[str]) -> None:
    folder.mkdir(exist_ok=True)
    for i, name in enumerate(names):
        assert cv2.imwrite(str(folder / name), numbered(10 * i))


# ---------------------------------------------------------------------- the image check


def test_check_bgr_image_accepts_and_rejects() -> None:
    img = numbered(3)
    assert check_bgr_image(img) is img
    view = np.zeros((H, W * 2, 3), np.uint8)[:, ::2]
    out = check_bgr_image(view)
    assert out.flags.c_contiguous and out.shape == (H, W, 3)
    for bad, words in [
        (np.zeros((H, W), np.uint8), "(48, 64)"),
        (np.zeros((H, W, 4), np.uint8), "(48, 64, 4)"),
        (np.zeros((H, W, 3), np.float32), "float32"),
        (np.zeros((0, W, 3), np.uint8), "empty"),
        ([[1, 2, 3]], "list"),
    ]:
        with pytest.raises(ConfigError) as err:
            check_bgr_image(bad)
        assert words in str(err.value)


# ---------------------------------------------------------------------- image folders


def test_folder_natural_order_sequence_and_timestamps(tmp_path: Path) -> None:
    write_images(tmp_path / "f", ["frame10.png", "frame2.png", "frame1.jpg", "notes.txt.png"])
    (tmp_path / "f" / "readme.txt").write_text("not an image")
    with ImageFolderSource(tmp_path / "f", pattern="frame*.png|frame*.jpg") as cam:
        assert isinstance(cam, CameraSource)
        assert (cam.width_px, cam.height_px) == (W, H)
        assert [p.name for p in cam.files] == ["frame1.jpg", "frame2.png", "frame10.png"]
        frames = list(cam.frames())
    assert [f.sequence for f in frames] == [0, 1, 2]
    assert [f.source for f in frames] == [str(tmp_path / "f")] * 3
    stamps = [f.timestamp_s for f in frames]
    assert stamps == sorted(stamps) and stamps[0] > 0
    # The images were written 0, 10, 20 in the order of the names list.
    assert [int(f.image[0, 0, 0]) for f in frames] == pytest.approx([20, 10, 0], abs=2)
    assert not frames[0].image.flags.writeable
    assert cam.closed
    with pytest.raises(CameraError, match="closed"):
        cam.read()


def test_folder_end_loop_and_grey_images(tmp_path: Path) -> None:
    folder = tmp_path / "g"
    folder.mkdir()
    cv2.imwrite(str(folder / "a.png"), np.full((H, W), 99, np.uint8))
    cv2.imwrite(str(folder / "b.png"), np.full((H, W), 150, np.uint8))
    cam = ImageFolderSource(folder)
    first, second = cam.read(), cam.read()
    assert first.image.shape == (H, W, 3) and int(first.image[0, 0, 1]) == 99
    assert int(second.image[5, 5, 2]) == 150
    with pytest.raises(EndOfFrames, match="after 2 image"):
        cam.read()
    looped = ImageFolderSource(folder, loop=True)
    values = [int(looped.read().image[0, 0, 0]) for _ in range(5)]
    assert values == [99, 150, 99, 150, 99]


def test_folder_unreadable_or_odd_image_names_the_file(tmp_path: Path) -> None:
    write_images(tmp_path / "u", ["a.png"])
    (tmp_path / "u" / "b.png").write_bytes(b"\x89PNG but not really")
    cam = ImageFolderSource(tmp_path / "u")
    cam.read()
    with pytest.raises(CameraError) as err:
        cam.read()
    assert str(tmp_path / "u" / "b.png") in str(err.value)
    # A first image that cannot be read fails at open.
    (tmp_path / "v").mkdir()
    (tmp_path / "v" / "0.jpg").write_bytes(b"")
    with pytest.raises(CameraError, match="0.jpg"):
        ImageFolderSource(tmp_path / "v")
    # Another size than the first image.
    (tmp_path / "s").mkdir()
    cv2.imwrite(str(tmp_path / "s" / "1.png"), numbered(1))
    cv2.imwrite(str(tmp_path / "s" / "2.png"), numbered(2, w=32))
    cam = ImageFolderSource(tmp_path / "s")
    cam.read()
    with pytest.raises(CameraError, match="32x48 px, the source is 64x48"):
        cam.read()


def test_folder_empty_missing_bad_pattern(tmp_path: Path) -> None:
    with pytest.raises(CameraError, match="no images matching"):
        ImageFolderSource(tmp_path)
    with pytest.raises(CameraError, match="no image folder"):
        ImageFolderSource(tmp_path / "nope")
    with pytest.raises(ConfigError, match="no glob"):
        ImageFolderSource(tmp_path, pattern=" | ")


# ---------------------------------------------------------------------- video files


def write_video(path: Path, count: int) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (W, H))
    assert writer.isOpened(), "OpenCV cannot write MJPG AVI here"
    for i in range(count):
        writer.write(numbered(40 * i))
    writer.release()


def test_video_file_frames_end_and_loop(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    write_video(path, 4)
    with VideoFileSource(path) as cam:
        assert isinstance(cam, CameraSource)
        assert (cam.width_px, cam.height_px) == (W, H) and cam.fps == pytest.approx(10.0)
        frames = [cam.read() for _ in range(4)]
        with pytest.raises(EndOfFrames, match="after 4 frame"):
            cam.read()
    assert [int(f.image[H // 2, W // 2, 0]) for f in frames] == pytest.approx(
        [0, 40, 80, 120], abs=4
    )
    looped = VideoFileSource(path, loop=True)
    values = [int(looped.read().image[H // 2, W // 2, 0]) for _ in range(6)]
    looped.close()
    assert values == pytest.approx([0, 40, 80, 120, 0, 40], abs=4)


def test_video_file_that_is_not_a_video(tmp_path: Path) -> None:
    bad = tmp_path / "bad.avi"
    bad.write_text("this is text")
    with pytest.raises(CameraError, match="bad.avi"):
        VideoFileSource(bad)
    with pytest.raises(CameraError, match="no video file"):
        VideoFileSource(tmp_path / "missing.mp4")


# ---------------------------------------------------------------------- USB cameras


class FakeCapture:
    """Stands in for cv2.VideoCapture: gives ``size`` whatever is asked."""

    size = (W, H)
    fps = 30.0
    frames = 3
    opened = True
    instances: ClassVar[list[FakeCapture]] = []

    def __init__(self, device: object, backend: int) -> None:
        self.device, self.backend = device, backend
        self.props: dict[int, float] = {}
        self.released = False
        self.reads = 0
        FakeCapture.instances.append(self)

    def isOpened(self) -> bool:  # OpenCV's name
        return self.opened

    def set(self, prop: int, value: float) -> bool:
        self.props[prop] = value
        return True

    def get(self, prop: int) -> float:
        if prop == cv2.CAP_PROP_FRAME_WIDTH:
            return float(self.size[0])
        if prop == cv2.CAP_PROP_FRAME_HEIGHT:
            return float(self.size[1])
        if prop == cv2.CAP_PROP_FPS:
            return self.fps
        return 0.0

    def read(self) -> tuple[bool, Any]:
        self.reads += 1
        if self.reads > self.frames:
            return False, None
        return True, numbered(self.reads, *self.size)

    def release(self) -> None:
        self.released = True


@pytest.fixture
def fake_usb(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> str:
    monkeypatch.setattr(camera_mod.cv2, "VideoCapture", FakeCapture)
    # Unset for the test, and put back as it was afterwards.
    monkeypatch.setenv(camera_mod.V4L_TIMEOUT_ENV, "-")
    monkeypatch.delenv(camera_mod.V4L_TIMEOUT_ENV)
    FakeCapture.instances = []
    device = tmp_path / "video0"  # exists, so the path check passes
    device.write_text("")
    return str(device)


def test_usb_camera_sets_the_format_and_reads(fake_usb: str) -> None:
    with UsbCamera(fake_usb, W, H, fps=30, fourcc="MJPG", read_timeout_s=0.5) as cam:
        cap = FakeCapture.instances[0]
        assert cap.props[cv2.CAP_PROP_FOURCC] == cv2.VideoWriter.fourcc(*"MJPG")
        assert (cap.props[cv2.CAP_PROP_FRAME_WIDTH], cap.props[cv2.CAP_PROP_FRAME_HEIGHT]) == (
            W, H)
        assert cap.props[cv2.CAP_PROP_READ_TIMEOUT_MSEC] == pytest.approx(500)
        assert os.environ[camera_mod.V4L_TIMEOUT_ENV] == "1"  # V4L2's own, whole seconds
        frames = [cam.read() for _ in range(3)]
        assert [int(f.image[0, 0, 0]) for f in frames] == [1, 2, 3]
        assert [f.sequence for f in frames] == [0, 1, 2]
        with pytest.raises(CameraError, match=r"no frame within 0\.5 s"):
            cam.read()
    assert cap.released


def test_usb_camera_reports_what_it_gave(fake_usb: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(FakeCapture, "size", (320, 240))
    with pytest.raises(CameraError) as err:
        UsbCamera(fake_usb, 640, 480)
    assert "gave 320x240 px, asked 640x480 YUYV at 30 fps" in str(err.value)
    assert FakeCapture.instances[-1].released
    monkeypatch.setattr(FakeCapture, "size", (W, H))
    monkeypatch.setattr(FakeCapture, "fps", 15.0)
    with pytest.warns(RuntimeWarning, match="runs at 15 fps, asked 30"):
        cam = UsbCamera(fake_usb, W, H)
    assert cam.actual_fps == 15.0
    cam.close()
    monkeypatch.setattr(FakeCapture, "frames", 0)
    with pytest.raises(CameraError, match="no frame within"):
        UsbCamera(fake_usb, W, H)
    monkeypatch.setattr(FakeCapture, "opened", False)
    with pytest.raises(CameraError, match="cannot be opened as a camera"):
        UsbCamera(fake_usb, W, H)


def test_usb_camera_bad_arguments_and_missing_device(tmp_path: Path) -> None:
    with pytest.raises(CameraError, match="^no camera at /dev/video-busarm-none$"):
        UsbCamera("/dev/video-busarm-none")
    with pytest.raises(ConfigError, match="fourcc 'H264'"):
        UsbCamera("/dev/video0", fourcc="H264")
    with pytest.raises(ConfigError, match=r"width_px = 8 is out of range 16\.\.8192"):
        UsbCamera("/dev/video0", width_px=8)
    with pytest.raises(ConfigError, match="camera index 300"):
        UsbCamera(300)


# ---------------------------------------------------------------------- open_camera


def open_fake_camera(spec: str, *, size: int = 8, label: str = "x") -> CameraSource:
    """A factory for the registry test: a source of ``size`` x ``size`` frames."""
    return _Fixed(f"{spec}|{label}", size)


class _Fixed(CameraBase):
    def __init__(self, name: str, size: int) -> None:
        super().__init__(name, size, size)

    def _grab(self) -> np.ndarray:
        return np.zeros((self.height_px, self.width_px, 3), np.uint8)

    def _release(self) -> None:
        pass


def test_open_camera_picks_the_source(tmp_path: Path) -> None:
    write_images(tmp_path / "imgs", ["a.png"])
    write_video(tmp_path / "v.avi", 2)
    with open_camera(str(tmp_path / "imgs")) as cam:
        assert isinstance(cam, ImageFolderSource)
    with open_camera(str(tmp_path / "imgs"), pattern="*.jpg|*.png", loop=True) as cam:
        assert isinstance(cam, ImageFolderSource) and cam.loop
    with open_camera(str(tmp_path / "v.avi")) as cam:
        assert isinstance(cam, VideoFileSource)
    with pytest.raises(CameraError, match="^no camera at /dev/video-busarm-none$"):
        open_camera("/dev/video-busarm-none")
    with pytest.raises(CameraError, match="^no camera at /dev/video251$"):
        open_camera("251")
    with pytest.raises(CameraError, match="^no camera at /dev/video252$"):
        open_camera(252)
    with pytest.raises(CameraError) as err:
        open_camera(str(tmp_path / "nothing.mp4"))
    assert str(err.value) == (
        f"no camera at {tmp_path / 'nothing.mp4'}: not a device, file, folder or known "
        "scheme (known: twin)"
    )
    with pytest.raises(ConfigError, match="camera must be"):
        open_camera("  ")


def test_open_camera_rejects_options_a_source_does_not_take(tmp_path: Path) -> None:
    write_images(tmp_path / "imgs", ["a.png"])
    with pytest.raises(ConfigError) as err:
        open_camera(str(tmp_path / "imgs"), fps=30)
    assert "fps not accepted" in str(err.value) and "pattern, loop" in str(err.value)


def test_scheme_registry(monkeypatch: pytest.MonkeyPatch) -> None:
    assert CAMERA_SCHEMES["twin"] == "busarm.twin.camera:open_twin_camera"
    monkeypatch.setitem(CAMERA_SCHEMES, "fake", f"{__name__}:open_fake_camera")
    with open_camera("fake") as cam:
        assert cam.name == "fake|x" and cam.read().image.shape == (8, 8, 3)
    with open_camera("fake://host/a?b=1", size=16, label="y") as cam:
        assert cam.name == "fake://host/a?b=1|y" and (cam.width_px, cam.height_px) == (16, 16)
    with pytest.raises(ConfigError, match="colour not accepted; it takes: size, label"):
        open_camera("fake", colour="red")
    monkeypatch.setitem(CAMERA_SCHEMES, "broken", "busarm.no_such_module:factory")
    with pytest.raises(CameraError, match="camera scheme 'broken': cannot load"):
        open_camera("broken://x")
    monkeypatch.setitem(CAMERA_SCHEMES, "notsource", f"{__name__}:W")
    with pytest.raises(CameraError, match="not callable"):
        open_camera("notsource")
    with pytest.raises(CameraError, match=r"known: broken, fake, notsource, twin\)"):
        open_camera("nothing-here")


def test_frame_dataclass() -> None:
    frame = CameraFrame(numbered(1), 12.5, 3, "cam")
    assert (frame.width_px, frame.height_px) == (W, H)
    assert frame == CameraFrame(numbered(2), 12.5, 3, "cam")  # the image is not compared
    with pytest.raises(AttributeError):
        frame.sequence = 4  # type: ignore[misc]
