"""The bridge's settings: one frozen, validated dataclass with units in the names.

Layers: defaults < JSON file (``manus bridge --config``) < command line. The
protocol's own constants (60 ms cycle, 20 ms slots and reply window) live in
:mod:`manus.protocol` and are not settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from manus.config import read_json_object
from manus.errors import ConfigError
from manus.protocol import JOINT_INC_MAX


def _range(name: str, value: float, lo: float, hi: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"bridge config: `{name}` must be in [{lo:g}, {hi:g}], got {value!r}")


@dataclass(frozen=True)
class BridgeConfig:
    """Every setting of the CAN bridge.

    Attributes:
        command_max_age_cycles: a velocity command is fresh if its ``ref_seq`` is at most
            this many joint states older than the newest one published [cycles].
        command_timeout_ms: a command with ``ref_seq = -1`` is fresh if it arrived at
            most this long before the sync [ms].
        sync_max_age_ms: a sync processed later than this after its arrival is not
            answered (it sat in a buffer: the reply could not reach the arm within the
            20 ms window) [ms].
        slot_tolerance_ms: how much earlier than its nominal time (20, 40, 60 ms after the
            cycle's start, on the grid of the recent syncs) a frame may arrive and still
            belong to that cycle; frames may be up to one cycle minus this late (< 10) [ms].
        clean_cycles_to_resume: clean cycles after a fault before commands reach the
            arm again [cycles].
        init_moves: the start-up moves of motors 4-6, one per sync (docs/protocol.md, Thesis
            start-up moves: four tiny moves in alternating directions, net zero) [counts =
            0.1 deg per 20 ms].
        power_up_timeout_ms: with no "absolute angles measured" message this long after
            the first cycle, assume the arm is ready (a bridge restarted after the arm) [ms].
        silence_timeout_ms: no frame from the arm for this long is reported as silence
            (and is a fault while running) [ms].
        fold_timeout_s: a fold not reported complete after this long ends in
            ``arm_error`` [s].
        fold_missed_cycles_to_stop: a fold with a deadman (``ArmCommand.heartbeat_timeout``
            > 0) answers a clean sync whose cycle gave no joint state or whose joint state
            the controller has not answered with zeros (the arm pauses); this many such
            syncs in a row stop it (phase ``stopped``; 5 = 300 ms, the controller's
            ``max_outage_ms``: a controller late under load pauses the fold, one that
            stays silent stops it) [cycles].
        max_field_step: largest plausible change of a position field per cycle; a larger
            jump marks the frame garbled [0.1 deg or 0.1 mm per cycle].
    """

    command_max_age_cycles: int = 0
    command_timeout_ms: float = 100.0
    sync_max_age_ms: float = 18.0
    slot_tolerance_ms: float = 9.0
    clean_cycles_to_resume: int = 2
    init_moves: tuple[int, ...] = (1, -1, 1, -1)
    power_up_timeout_ms: float = 3000.0
    silence_timeout_ms: float = 200.0
    fold_timeout_s: float = 90.0
    fold_missed_cycles_to_stop: int = 5
    max_field_step: int = 60

    def __post_init__(self) -> None:
        if not isinstance(self.command_max_age_cycles, int) or not (
            0 <= self.command_max_age_cycles <= 10
        ):
            raise ConfigError(
                "bridge config: `command_max_age_cycles` must be an integer in [0, 10], "
                f"got {self.command_max_age_cycles!r}"
            )
        _range("command_timeout_ms", self.command_timeout_ms, 1.0, 10_000.0)
        _range("sync_max_age_ms", self.sync_max_age_ms, 0.0, 20.0)
        _range("slot_tolerance_ms", self.slot_tolerance_ms, 0.5, 9.9)
        if not isinstance(self.clean_cycles_to_resume, int) or not (
            1 <= self.clean_cycles_to_resume <= 100
        ):
            raise ConfigError(
                "bridge config: `clean_cycles_to_resume` must be an integer in [1, 100], "
                f"got {self.clean_cycles_to_resume!r}"
            )
        object.__setattr__(self, "init_moves", tuple(self.init_moves))
        for i, m in enumerate(self.init_moves):
            if not isinstance(m, int) or not -JOINT_INC_MAX <= m <= JOINT_INC_MAX:
                raise ConfigError(
                    f"bridge config: `init_moves[{i}]` = {m!r} outside "
                    f"-{JOINT_INC_MAX}..{JOINT_INC_MAX} counts"
                )
        _range("power_up_timeout_ms", self.power_up_timeout_ms, 0.0, 600_000.0)
        _range("silence_timeout_ms", self.silence_timeout_ms, 70.0, 60_000.0)
        _range("fold_timeout_s", self.fold_timeout_s, 1.0, 3600.0)
        if not isinstance(self.fold_missed_cycles_to_stop, int) or not (
            1 <= self.fold_missed_cycles_to_stop <= 100
        ):
            raise ConfigError(
                "bridge config: `fold_missed_cycles_to_stop` must be an integer in [1, 100], "
                f"got {self.fold_missed_cycles_to_stop!r}"
            )
        if not isinstance(self.max_field_step, int) or not 1 <= self.max_field_step <= 32767:
            raise ConfigError(
                "bridge config: `max_field_step` must be an integer in [1, 32767], "
                f"got {self.max_field_step!r}"
            )

    @classmethod
    def from_mapping(cls, data: dict[str, Any], *, source: str = "<mapping>") -> BridgeConfig:
        """Build from JSON-like data whose keys are the field names.

        Raises:
            ConfigError: naming the source and the key.
        """
        known = {f.name for f in fields(cls)}
        for key in data:
            if key not in known:
                raise ConfigError(f"{source}: unknown bridge setting `{key}` ({sorted(known)})")
        kwargs: dict[str, Any] = {
            k: tuple(v) if isinstance(v, list) else v for k, v in data.items()
        }
        try:
            return cls(**kwargs)
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}") from exc
        except TypeError as exc:
            raise ConfigError(f"{source}: {exc}") from exc


def load_bridge_config(path: str | None) -> BridgeConfig:
    """Defaults, or defaults < the JSON file at ``path``.

    Raises:
        ConfigError: the file cannot be read, is not JSON, or holds a bad setting.
    """
    if not path:
        return BridgeConfig()
    file = Path(path)
    return BridgeConfig.from_mapping(read_json_object(file, "bridge config"), source=str(file))
