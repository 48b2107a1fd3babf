"""Arm configuration: defaults, file layer, validation messages."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from manus.config import DEG, ArmConfig, load_arm_config
from manus.errors import ConfigError


def test_defaults_are_the_thesis_arm() -> None:
    cfg = ArmConfig()
    assert (cfg.l1, cfg.l2, cfg.l3, cfg.l4) == (0.105, 0.4, 0.32, 0.16)
    assert cfg.max_speed == pytest.approx([50 * DEG] * 6)
    assert cfg.upper[4] < math.pi and cfg.upper[0] > math.pi  # joint 5 finite, others turn


def test_file_in_thesis_units(tmp_path: Path) -> None:
    f = tmp_path / "arm.json"
    f.write_text(json.dumps({"l2_mm": 396.7, "max_speed_deg_s": [30] * 6}))
    cfg = load_arm_config(f)
    assert cfg.l2 == pytest.approx(0.3967)
    assert cfg.max_speed == pytest.approx([30 * DEG] * 6)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ('{"l2_mm": "long"}', r"arm.json: `l2_mm` must be numeric, got 'long'"),
        ('{"wingspan_mm": 3}', r"arm.json: unknown arm setting `wingspan_mm`"),
        (
            '{"max_speed_deg_s": [60, 50, 50, 50, 50, 50]}',
            r"joint 1: `max_speed` 60.00 deg/s must be in \(0, 50\]",
        ),
        (
            '{"lower_deg": [0, 0, 0, 0, 10, 0], "upper_deg": [1, 1, 1, 1, 5, 1]}',
            "joint 5: lower limit 10.0 deg must be below upper limit 5.0 deg",
        ),
        ('{"l1_mm": 1', r"arm.json:1: not valid JSON"),
    ],
)
def test_bad_files_are_named(tmp_path: Path, content: str, match: str) -> None:
    f = tmp_path / "arm.json"
    f.write_text(content)
    with pytest.raises(ConfigError, match=match):
        load_arm_config(f)
