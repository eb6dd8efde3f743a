"""The chassis config: the shipped JetAuto, and one clear error for each bad file."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from busarm.base.config import WHEELS, chassis_config_from_toml, load_chassis_config
from busarm.errors import ConfigError

SHIPPED = Path(__file__).parents[2] / "src/busarm/base/configs/jetauto.toml"


def test_shipped_jetauto_has_the_field_notes_numbers() -> None:
    cfg = load_chassis_config("jetauto")
    assert cfg.wheel_diameter_m == pytest.approx(0.0965)
    assert cfg.track_m == pytest.approx(0.218)
    assert cfg.wheelbase_m == pytest.approx(0.195)
    assert cfg.encoder_ticks_per_rev == 3960
    assert cfg.max_wheel_rev_s == 1.5
    assert [m.motor for m in cfg.motors] == [1, 2, 3, 4]
    assert [m.sign for m in cfg.motors] == [-1, -1, 1, 1]
    assert cfg.max_yaw_rate_rad_s == pytest.approx(math.radians(120))
    assert cfg.command_timeout_s == 0.5
    assert len(WHEELS) == 4


def test_a_file_by_path_reads_as_the_shipped_one(tmp_path: Path) -> None:
    path = tmp_path / "mine.toml"
    path.write_text(SHIPPED.read_text().replace("track_mm = 218.0", "track_mm = 300.0"))
    assert load_chassis_config(path).track_m == pytest.approx(0.3)


@pytest.mark.parametrize(("old", "new", "said"), [
    ("[limits]", "[limits]\nmax_sped = 1", ["limits", "max_sped", "max_speed_m_s"]),
    ("name = ", "colour = 'red'\nname = ", ["colour"]),
    ("track_mm = 218.0", "track_mm = 2.0", ["wheels.track_mm", "2.0", "10..5000"]),
    ("max_speed_m_s = 0.40", "max_speed_m_s = 0", ["limits.max_speed_m_s", "0", "0.01..10"]),
    ("command_timeout_s = 0.5", "command_timeout_s = 20",
     ["limits.command_timeout_s", "20", "0.05..10"]),
    ("max_rev_s = 1.5", "max_rev_s = 'fast'", ["wheels.max_rev_s", "'fast'"]),
    ("rear_right = { motor = 4, sign = 1 }", "rear_right = { motor = 3, sign = 1 }",
     ["wheels.motors", "[1, 2, 3, 3]"]),
    ("front_left = { motor = 1, sign = -1 }", "front_left = { motor = 1, sign = 0 }",
     ["wheels.motors.front_left.sign", "0"]),
])
def test_a_bad_value_is_one_error_naming_key_value_and_range(old: str, new: str,
                                                             said: list[str]) -> None:
    text = SHIPPED.read_text()
    assert old in text
    with pytest.raises(ConfigError) as caught:
        chassis_config_from_toml(text.replace(old, new, 1), "bad.toml")
    message = str(caught.value)
    assert "bad.toml" in message and "\n" not in message
    for part in said:
        assert part in message, message
