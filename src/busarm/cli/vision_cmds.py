"""``vision``: cameras and detectors from the command line (no bus needed).

``vision detect`` reads frames from a camera source (a USB camera, a video file, a
folder of images, or a scheme such as ``twin``) and prints each colour block found:
colour, centroid in pixels, yaw and area. The vision modules (and OpenCV) are imported
only when a vision command runs, so the rest of ``busarm`` starts as fast as before.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from busarm.cli.common import RangeType, no_servos
from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.vision.camera import CameraFrame
    from busarm.vision.color import ColorDetector, Detection
    from busarm.vision.color_thresholds import ColorThresholds
    from busarm.vision.tags import TagDetection

__all__ = [
    "AREA",
    "COMMANDS",
    "DEFAULT_MIN_AREA_PX",
    "detect",
    "vision",
]


DEFAULT_MIN_AREA_PX = 200.0
"""Same as busarm.vision.color.DEFAULT_MIN_AREA_PX (kept here to avoid importing OpenCV)."""
AREA = RangeType("area", 0.0, 1e9, "px")

_CAMERA_HELP = (
    "Camera source: /dev/videoN or N (USB camera), a video file, a folder of images, a "
    "network stream (rtsp://, http://, https:// URL) or a scheme (twin, twin://...)."
)


@click.group()
def vision() -> None:
    """Cameras and detectors: colour blocks (Lab thresholds) and AprilTags.

    Pixel coordinates: u right, v down, integers at pixel centres; yaw in degrees from
    +u towards +v, modulo 90 (a square block looks the same every quarter turn).
    """


def _load_thresholds(ctx: click.Context, thresholds: str | None, vendor_yaml: str | None,
                     section: str) -> ColorThresholds:
    from busarm.vision.color_thresholds import default_thresholds, load_thresholds

    if thresholds is not None and vendor_yaml is not None:
        raise ConfigError("give --thresholds or --vendor-yaml, not both")
    path = vendor_yaml if vendor_yaml is not None else thresholds
    section_given = ctx.get_parameter_source("section") is not click.core.ParameterSource.DEFAULT
    if vendor_yaml is not None and Path(vendor_yaml).suffix.lower() not in (".yaml", ".yml"):
        raise ConfigError(f"--vendor-yaml {vendor_yaml}: expected a .yaml/.yml file "
                          "(the vendor's lab_config.yaml)")
    if section_given and (path is None or Path(path).suffix.lower() not in (".yaml", ".yml")):
        raise ConfigError("--section applies to the vendor's YAML thresholds only")
    if path is None:
        return default_thresholds()
    return load_thresholds(path, section=section)


def _nothing_found(detector: ColorDetector, image: Any) -> str:
    """Why no block was reported: no pixel in the colour boxes, or only small blobs."""
    import numpy as np

    spread = np.ptp(np.asarray(image).reshape(-1, 3), axis=0)
    if int(spread.max()) <= 8:
        return ("no blocks found: the frame is uniform (blank, covered, or saturated): "
                "check the lens cap, the exposure and the lighting")
    counts = detector.matched_pixels(image)
    names = ", ".join(detector.colors)
    if not any(counts.values()):
        return f"no blocks found: thresholds for {names} matched no pixels"
    matched = ", ".join(f"{c} {n} px" for c, n in counts.items() if n)
    return (f"no blocks found: {matched} matched, but no blob reaches the minimum area "
            f"{detector.min_area_px:g} px")


def _frame_text(frame: CameraFrame, index: int, detections: list[Detection],
                tags: list[TagDetection] | None, note: str | None) -> str:
    head = f"frame {index} ({frame.width_px}x{frame.height_px} px, t={frame.timestamp_s:.3f} s)"
    lines = []
    if note is not None:
        lines.append(f"{head}: {note}")
    else:
        lines.append(f"{head}: {len(detections)} block(s)")
        for d in detections:
            lines.append(
                f"  {d.color:<8} centroid ({d.centroid_px[0]:7.2f}, {d.centroid_px[1]:7.2f}) px  "
                f"yaw {d.yaw_deg:+6.1f} deg  area {d.area_px:8.0f} px"
            )
    if tags is not None:
        if not tags:
            lines.append("  no AprilTags (36h11) found")
        for t in tags:
            lines.append(f"  tag {t.tag_id:<4} center ({t.center_px[0]:7.2f}, "
                         f"{t.center_px[1]:7.2f}) px")
    return "\n".join(lines)


@vision.command()
@click.option("--camera", "camera", envvar="BUSARM_CAMERA", show_envvar=True, required=True,
              help=_CAMERA_HELP)
@click.option("--thresholds", type=click.Path(dir_okay=False),
              help="Colour thresholds: busarm TOML or the vendor's lab_config.yaml "
                   " [default: the shipped red, green, blue, yellow]")
@click.option("--vendor-yaml", type=click.Path(dir_okay=False),
              help="The vendor's lab_config.yaml (same as --thresholds FILE.yaml).")
@click.option("--section", type=click.Choice(["Mono", "Stereo"]), default="Mono",
              show_default=True, help="Which camera's thresholds in the vendor's YAML.")
@click.option("--colors", help="Comma-separated colours to look for  [default: all defined]")
@click.option("--frames", "frame_count", type=click.IntRange(0, 10_000_000), default=1,
              show_default=True,
              help="Frames to read; 0 = until the video or folder ends (or Ctrl+C).")
@click.option("--min-area", "min_area_px", type=AREA, default=DEFAULT_MIN_AREA_PX,
              show_default=True, help="Smallest blob, in pixels at full resolution.")
@click.option("--tags", "find_tags", is_flag=True, help="Also find AprilTags (36h11).")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per frame.")
@click.option("--save", "save_dir", type=click.Path(file_okay=False),
              help="Write each annotated frame to DIRECTORY/frame_NNNNNN.png.")
@click.pass_context
@no_servos
def detect(
    ctx: click.Context, camera: str, thresholds: str | None,
    vendor_yaml: str | None, section: str, colors: str | None, frame_count: int,
    min_area_px: float, find_tags: bool, as_json: bool, save_dir: str | None,
) -> None:
    """Find colour blocks in camera frames: colour, centroid (px), yaw (deg), area (px)."""
    from busarm.cli.common import camera_from_text
    from busarm.vision.annotate import annotate, save_image
    from busarm.vision.camera import EndOfFrames
    from busarm.vision.color import ColorDetector
    from busarm.vision.color_thresholds import parse_color_names
    from busarm.vision.tags import detect_tags

    table = _load_thresholds(ctx, thresholds, vendor_yaml, section)
    names = parse_color_names(colors) if colors is not None else None
    detector = ColorDetector(table, names, min_area_px=min_area_px)
    out_dir: Path | None = None
    if save_dir is not None:
        out_dir = Path(save_dir)
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"--save {out_dir}: cannot create the folder: {exc}") from None
    with camera_from_text(camera) as source:
        index = 0
        while frame_count == 0 or index < frame_count:
            try:
                frame = source.read()
            except EndOfFrames:
                if frame_count == 0:
                    break  # "until it ends" was asked for
                raise
            detections = detector.detect(frame.image)
            tags = detect_tags(frame.image) if find_tags else None
            note = None if detections else _nothing_found(detector, frame.image)
            if as_json:
                data: dict[str, Any] = {
                    "frame": index, "sequence": frame.sequence,
                    "timestamp_s": round(frame.timestamp_s, 6), "source": frame.source,
                    "width_px": frame.width_px, "height_px": frame.height_px,
                    "detections": [d.to_dict() for d in detections],
                }
                if tags is not None:
                    data["tags"] = [t.to_dict() for t in tags]
                if note is not None:
                    data["note"] = note
                click.echo(json.dumps(data))
            else:
                # Plain lines, never wrapped: scripts read them.
                click.echo(_frame_text(frame, index, detections, tags, note))
            if out_dir is not None:
                lines = [f"{source.name} frame {index}"] + ([note] if note else [])
                save_image(out_dir / f"frame_{index:06d}.png",
                           annotate(frame.image, detections, tags or (), lines))
            index += 1


COMMANDS = [vision]
