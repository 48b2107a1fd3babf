"""A game controller or joystick for ``manus jog --joystick``: Linux input events -> jog.

Events are (type, code, value) with the kernel's names (``EV_ABS`` / ``ABS_X``,
``EV_KEY`` / ``BTN_SOUTH``), read from ``/dev/input/event*`` with the ``evdev`` package
(``pip install -e '.[joystick]'``) or from a recorded session (:class:`RecordedEvents`:
JSON lines ``{"t": s, "type": ..., "code": ..., "value": ...}``, with the axes' ranges
in a first line ``{"absinfo": {"ABS_X": [min, max], ...}}``), so the mapping is tested
without a device.

The **axis mapping** is a JSON file (:meth:`JoystickMap.from_file`; the default,
:data:`DEFAULT_MAP`, is a gamepad as the Linux ``xpad`` driver reports one)::

    {"axes": {"ABS_Y": {"to": "x", "scale": -1.0}, "ABS_X": {"to": "y", "scale": -1.0},
              "ABS_RY": {"to": "z", "scale": -1.0}, "ABS_RX": {"to": "yaw", "scale": -1.0}},
     "buttons": {"BTN_SOUTH": "stop", "BTN_TR": "level_up", "BTN_TL": "level_down"},
     "deadzone": 0.12, "enable": "BTN_TL2"}

Axes go to ``x y z roll pitch yaw`` (joints 1-6 in joint mode), ``gripper`` or ``pour``;
each is scaled from its range to -1..1 (times ``scale``), and values within ``deadzone``
of the centre count as zero. Buttons: ``stop``, ``level_up``, ``level_down``, ``frame``,
``joint_mode``, ``drink``, ``gripper_open``, ``gripper_close``. With ``enable`` set,
the stick moves the arm only while that button is held (a second deadman). The keyboard
keeps working beside it (:class:`Joystick` is a :class:`~manus_stack.teleop.Teleop`).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from manus.errors import ConfigError
from manus_stack.teleop import Teleop

TARGETS = ("x", "y", "z", "roll", "pitch", "yaw", "gripper", "pour")
"""Where an axis can go: the eight deflections of :meth:`Teleop.values`, in order."""
ACTIONS = {"stop": " ", "frame": "b", "joint_mode": "t", "drink": "c"}
"""Button action -> the teleop key that does the same."""
BUTTON_ACTIONS = (*ACTIONS, "level_up", "level_down", "gripper_open", "gripper_close")

DEFAULT_MAP: dict[str, Any] = {
    "axes": {
        "ABS_Y": {"to": "x", "scale": -1.0},  # left stick forward: +x
        "ABS_X": {"to": "y", "scale": -1.0},  # left stick left: +y
        "ABS_RY": {"to": "z", "scale": -1.0},  # right stick forward: up
        "ABS_RX": {"to": "yaw", "scale": -1.0},
        "ABS_HAT0Y": {"to": "pitch", "scale": -1.0},
        "ABS_HAT0X": {"to": "roll", "scale": 1.0},
    },
    "buttons": {
        "BTN_SOUTH": "stop",
        "BTN_TR": "level_up",
        "BTN_TL": "level_down",
        "BTN_NORTH": "frame",
        "BTN_WEST": "drink",
        "BTN_SELECT": "joint_mode",
        "BTN_EAST": "gripper_open",
        "BTN_START": "gripper_close",
    },
    "deadzone": 0.12,
    "enable": "",
}


@dataclass(frozen=True)
class JoystickMap:
    """Which axis and button does what (see the module docstring).

    Attributes:
        axes: axis code name -> (target, scale).
        buttons: button code name -> action.
        deadzone: deflections within this of the centre are zero [-], in [0, 0.9].
        enable: a button that must be held for the sticks to move the arm ('': none).
        source: where the mapping came from (for errors).
    """

    axes: dict[str, tuple[str, float]]
    buttons: dict[str, str]
    deadzone: float = 0.12
    enable: str = ""
    source: str = "the default mapping"

    @classmethod
    def from_dict(cls, data: Any, source: str = "the default mapping") -> JoystickMap:
        """Validate a mapping.

        Raises:
            ConfigError: naming the file, the key, the value and what is allowed.
        """
        if not isinstance(data, dict):
            raise ConfigError(f"{source}: expected a JSON object")
        unknown = set(data) - {"axes", "buttons", "deadzone", "enable"}
        if unknown:
            raise ConfigError(f"{source}: unknown key(s) {sorted(unknown)}")
        axes: dict[str, tuple[str, float]] = {}
        for code, spec in dict(data.get("axes", {})).items():
            target = spec.get("to") if isinstance(spec, dict) else None
            scale = spec.get("scale", 1.0) if isinstance(spec, dict) else None
            if target not in TARGETS:
                raise ConfigError(f"{source}: axes.{code}.to {target!r} is not one of {TARGETS}")
            if not isinstance(scale, int | float) or not -10.0 <= scale <= 10.0:
                raise ConfigError(f"{source}: axes.{code}.scale {scale!r} must be in -10..10")
            axes[str(code)] = (target, float(scale))
        buttons = {str(k): v for k, v in dict(data.get("buttons", {})).items()}
        for code, action in buttons.items():
            if action not in BUTTON_ACTIONS:
                raise ConfigError(
                    f"{source}: buttons.{code} {action!r} is not one of {list(BUTTON_ACTIONS)}"
                )
        deadzone = data.get("deadzone", 0.12)
        if not isinstance(deadzone, int | float) or not 0.0 <= deadzone <= 0.9:
            raise ConfigError(f"{source}: deadzone {deadzone!r} must be in [0, 0.9]")
        enable = data.get("enable", "")
        if not isinstance(enable, str):
            raise ConfigError(f"{source}: enable {enable!r} must be a button name or ''")
        return cls(axes, buttons, float(deadzone), enable, source)

    @classmethod
    def from_file(cls, path: str | Path) -> JoystickMap:
        """Read a mapping file (JSON)."""
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ConfigError(f"{path}: cannot read the joystick mapping: {exc}") from exc
        return cls.from_dict(data, str(path))


@dataclass
class Joystick(Teleop):
    """The teleop with a joystick beside the keyboard (see the module docstring).

    Attributes:
        mapping: what each axis and button does.
        ranges: axis code name -> (min, max) raw values (the device's absinfo).
        sticks: the current deflection of each target, after the dead zone [-1, 1].
        enabled: the ``enable`` button is held (or none is configured).
        level: the speed level the buttons step from.
    """

    mapping: JoystickMap = field(default_factory=lambda: JoystickMap.from_dict(DEFAULT_MAP))
    ranges: dict[str, tuple[int, int]] = field(default_factory=dict)
    sticks: dict[str, float] = field(default_factory=dict)
    enabled: bool = True
    level: int = 3

    def __post_init__(self) -> None:
        self.enabled = not self.mapping.enable

    def event(self, type_name: str, code: str, value: int, now_s: float) -> int | None:
        """One input event; returns a speed level to set (None: none)."""
        if type_name == "EV_ABS" and code in self.mapping.axes:
            target, scale = self.mapping.axes[code]
            lo, hi = self.ranges.get(code, (-32768, 32767))
            v = (2.0 * (value - lo) / (hi - lo) - 1.0) * scale if hi > lo else 0.0
            dz = self.mapping.deadzone
            v = max(-1.0, min(1.0, v))
            self.sticks[target] = (
                0.0 if abs(v) <= dz else (abs(v) - dz) / (1.0 - dz) * (1.0 if v > 0 else -1.0)
            )
        elif type_name == "EV_KEY":
            if code == self.mapping.enable:
                self.enabled = value != 0
                return None
            action = self.mapping.buttons.get(code)
            if action is None or value != 1:  # presses only (not releases, not repeats)
                return None
            if action in ACTIONS:
                self.key(ACTIONS[action], now_s)
            elif action in ("gripper_open", "gripper_close"):
                self.key("]" if action == "gripper_open" else "[", now_s)
            else:
                step = 1 if action == "level_up" else -1
                wanted = max(1, min(self.levels, self.level + step))
                if wanted != self.level:
                    self.level = wanted
                    self.status = f"level {wanted}"
                    return wanted
        return None

    def values(self, now_s: float) -> list[float]:
        """The keyboard's held keys, overlaid by the sticks (while enabled)."""
        out = super().values(now_s)
        if not self.enabled:
            return out
        for i, target in enumerate(TARGETS):
            v = self.sticks.get(target, 0.0) * self.deflection
            if target == "pitch" and self.drink:  # pitch is held: the stick pours
                out[7] = out[7] or v
                continue
            if target == "roll" and self.drink:
                continue
            if v:
                out[i] = v
        return out


class RecordedEvents:
    """A recorded input session (JSON lines, see the module docstring), played back in
    real time from the first :meth:`due` call.

    Args:
        path: the recording.
    """

    def __init__(self, path: str | Path) -> None:
        self.ranges: dict[str, tuple[int, int]] = {}
        self.events: list[tuple[float, str, str, int]] = []
        for number, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), 1):
            if not line.strip():
                continue
            try:
                item = json.loads(line)
                if "absinfo" in item:
                    self.ranges |= {k: (int(v[0]), int(v[1])) for k, v in item["absinfo"].items()}
                else:
                    t, kind, code = float(item["t"]), str(item["type"]), str(item["code"])
                    self.events.append((t, kind, code, int(item["value"])))
            except (ValueError, KeyError, TypeError, IndexError) as exc:
                raise ConfigError(f"{path}:{number}: not an input event: {exc}") from exc
        self.events.sort(key=lambda e: e[0])
        self._start: float | None = None
        self._next = 0

    def due(self, now_s: float) -> Iterator[tuple[str, str, int]]:
        """The events whose time has come by ``now_s`` [s] (the first call starts the clock)."""
        if self._start is None:
            self._start = now_s
        while self._next < len(self.events) and self.events[self._next][0] <= now_s - self._start:
            _, kind, code, value = self.events[self._next]
            self._next += 1
            yield kind, code, value

    @property
    def done(self) -> bool:
        """Every event has been played."""
        return self._next >= len(self.events)
