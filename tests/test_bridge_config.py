"""BridgeConfig validation and the `manus bridge` channel resolution: errors that say what."""

from __future__ import annotations

from pathlib import Path

import pytest

from manus.errors import ConfigError
from services.can_bridge.config import BridgeConfig, load_bridge_config
from services.can_bridge.main import resolve_channel


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"command_timeout_ms": 0.0}, "`command_timeout_ms` must be in [1, 10000], got 0.0"),
        ({"sync_max_age_ms": 25.0}, "`sync_max_age_ms` must be in [0, 20], got 25.0"),
        ({"slot_tolerance_ms": 12.0}, "`slot_tolerance_ms` must be in [0.5, 9.9], got 12.0"),
        ({"init_moves": (1, -11)}, "`init_moves[1]` = -11 outside -10..10 counts"),
        ({"clean_cycles_to_resume": 0}, "`clean_cycles_to_resume` must be an integer in [1, 100]"),
        ({"command_max_age_cycles": -1}, "`command_max_age_cycles` must be an integer in [0, 10]"),
        ({"silence_timeout_ms": 50.0}, "`silence_timeout_ms` must be in [70, 60000], got 50.0"),
        ({"max_field_step": 0}, "`max_field_step` must be an integer in [1, 32767], got 0"),
    ],
)
def test_bad_settings_name_field_value_and_limit(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError) as info:
        BridgeConfig(**kwargs)  # type: ignore[arg-type]
    assert message in str(info.value)


def test_file_layer(tmp_path: Path) -> None:
    good = tmp_path / "bridge.json"
    good.write_text('{"command_timeout_ms": 150, "init_moves": [2, -2]}')
    cfg = load_bridge_config(str(good))
    assert cfg.command_timeout_ms == 150 and cfg.init_moves == (2, -2)
    assert load_bridge_config(None) == BridgeConfig()
    bad = tmp_path / "bad.json"
    bad.write_text('{\n"command_timeout_ms": 150,\n"colour": 3\n}')
    with pytest.raises(ConfigError, match=r"bad.json: unknown bridge setting `colour`"):
        load_bridge_config(str(bad))
    broken = tmp_path / "broken.json"
    broken.write_text('{\n"command_timeout_ms": \n}')
    with pytest.raises(ConfigError, match=r"broken.json:3: not valid JSON"):
        load_bridge_config(str(broken))


def test_channel_from_the_simulators_device_file(tmp_path: Path) -> None:
    device = tmp_path / "device"
    assert resolve_channel("socketcan", "can0", str(device), 0.0) == "can0"
    with pytest.raises(ConfigError, match=r"give --can-channel, or start `manus sim"):
        resolve_channel("slcan", "", str(device), 0.05)
    device.write_text("/dev/pts/7")
    assert resolve_channel("slcan", "", str(device), 0.0) == "/dev/pts/7"
