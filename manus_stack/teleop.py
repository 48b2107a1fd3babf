"""The keyboard teleop's model: keys in, jog commands and a status screen out.

No terminal and no bus here (``manus jog`` in :mod:`manus_stack.commands.jog` adds both),
so the mapping is tested alone. A terminal sends no key releases, only presses and the
keyboard's auto-repeat, so a key **holds** its axis for ``hold_s`` after its last press
(longer than the usual auto-repeat delay of 0.25-0.6 s): hold the key to keep moving,
let go and the axis stops ``hold_s`` later; space stops everything at once.

Keys (Cartesian mode; the same keys drive joints 1-6 in joint mode):

    w / s   +x / -x        (joint 1)      u / o   +roll / -roll    (joint 4)
    a / d   +y / -y        (joint 2)      i / k   +pitch / -pitch  (joint 5)
    r / f   +z / -z        (joint 3)      j / l   +yaw / -yaw      (joint 6)
    ] / [   open / close the gripper      1..5    speed level
    b       base / gripper frame          t       joint mode on / off
    c       drink mode on / off (i / k pour, pitch and roll held)
    space   stop                          q       quit (stops first)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

AXES = {"w": (0, 1.0), "s": (0, -1.0), "a": (1, 1.0), "d": (1, -1.0), "r": (2, 1.0),
        "f": (2, -1.0), "u": (3, 1.0), "o": (3, -1.0), "i": (4, 1.0), "k": (4, -1.0),
        "j": (5, 1.0), "l": (5, -1.0)}  # fmt: skip
"""Key -> (axis, sign): axes 0-2 linear x, y, z; 3-5 angular x (roll), y (pitch), z
(yaw); in joint mode axis n is joint n + 1."""
GRIPPER_KEYS = {"]": 1.0, "[": -1.0}
LEVEL_KEYS = "123456789"


@dataclass
class Teleop:
    """What the user holds and has chosen (see the module docstring).

    Attributes:
        hold_s: how long a key press keeps its axis moving [s].
        deflection: fraction of the level's speed per key, in (0, 1].
        frame: ``base`` or ``gripper``.
        joint_mode: keys drive joints instead of the gripper's twist.
        drink: drink mode (pitch and roll held; i / k pour).
        levels: speed levels the controller offers.
        held: axis -> (sign, time of the last press [s]); axis 6 is the gripper, 7 the pour.
    """

    hold_s: float = 0.6
    deflection: float = 1.0
    frame: str = "base"
    joint_mode: bool = False
    drink: bool = False
    levels: int = 5
    held: dict[int, tuple[float, float]] = field(default_factory=dict)
    quit: bool = False
    status: str = ""
    """The outcome of the last key, in words."""

    def key(self, ch: str, now_s: float) -> int | None:
        """Take one key press at ``now_s`` [s]; returns a speed level to set (None: none)."""
        if ch == " ":
            self.held.clear()
            self.status = "stop"
        elif ch == "q":
            self.held.clear()
            self.quit = True
        elif ch == "b":
            self.held.clear()
            self.frame = "gripper" if self.frame == "base" else "base"
            self.status = f"frame {self.frame}"
        elif ch == "t":
            self.held.clear()
            self.joint_mode, self.drink = not self.joint_mode, False
            self.status = "joint mode" if self.joint_mode else "Cartesian mode"
        elif ch == "c":
            self.held.clear()
            self.drink, self.joint_mode = not self.drink, False
            self.status = "drink mode: the cup stays level" if self.drink else "drink mode off"
        elif ch in LEVEL_KEYS and int(ch) <= self.levels:
            self.status = f"level {ch}"
            return int(ch)
        elif ch in GRIPPER_KEYS:
            self.held[6] = (GRIPPER_KEYS[ch], now_s)
        elif ch in AXES:
            axis, sign = AXES[ch]
            if self.drink and axis in (3, 4):  # pitch and roll are held: i / k pour
                if axis == 4:
                    self.held[7] = (sign, now_s)
                else:
                    self.status = "drink mode holds the roll"
                return None
            self.held[axis] = (sign, now_s)
        return None

    def values(self, now_s: float) -> list[float]:
        """The eight deflections held at ``now_s``: six axes, the gripper, the pour."""
        out = [0.0] * 8
        for axis, (sign, t) in list(self.held.items()):
            if now_s - t > self.hold_s:
                del self.held[axis]
            else:
                out[axis] = sign * self.deflection
        return out

    def command(self, now_s: float) -> dict[str, Any]:
        """The JogCommand fields (unitless) for ``now_s`` [s] (kind ``stop`` when idle)."""
        v = self.values(now_s)
        if not any(v):
            return {"kind": "stop", "units": "unitless"}
        if self.joint_mode:
            return {"kind": "joints", "units": "unitless", "joints": v[:6], "gripper": v[6]}
        angular = [0.0, 0.0, v[5]] if self.drink else v[3:6]
        return {"kind": "twist", "units": "unitless", "frame": self.frame, "linear": v[:3],
                "angular": angular, "gripper": v[6], "drink": self.drink,
                "pour": v[7] if self.drink else 0.0}  # fmt: skip

    def mode(self) -> str:
        """The mode in words."""
        if self.joint_mode:
            return "joint"
        return f"{'drink' if self.drink else 'Cartesian'}, {self.frame} frame"


def screen(teleop: Teleop, now_s: float, jog: Any, status: Any, bridge: Any) -> list[str]:
    """The lines to show: mode, level, pose, why the jog is slowed or stopped, the arm's
    warnings. ``jog`` is the newest JogState (or None), ``status`` the newest ArmStatus,
    ``bridge`` the newest BridgeState (either None when none came)."""
    v = teleop.values(now_s)
    names = [f"q{i}" for i in range(1, 7)] if teleop.joint_mode else ["x", "y", "z", "roll",
                                                                       "pitch", "yaw"]  # fmt: skip
    held = " ".join(f"{n}{'+' if s > 0 else '-'}" for n, s in zip(names, v, strict=False) if s)
    held += " grip+" if v[6] > 0 else " grip-" if v[6] < 0 else ""
    held += " pour+" if v[7] > 0 else " pour-" if v[7] < 0 else ""
    lines = ["manus jog   (q quits, space stops; keys: manus jog --help)"]
    level = f"{jog.level}/{jog.levels}" if jog is not None else "?"
    lines.append(f"mode: {teleop.mode()}   level: {level}   moving: {held.strip() or '-'}")
    if jog is not None:
        xyz = " ".join(f"{v * 1000.0:7.1f}" for v in jog.actual_xyz)
        ypr = " ".join(f"{math.degrees(v):6.1f}" for v in jog.actual_ypr)
        lines.append(f"gripper xyz [mm] {xyz}   yaw pitch roll [deg] {ypr}")
        state = "jogging" if jog.active else "stopped"
        lines.append(f"jog: {state}  refused {jog.refused}  deadman stops {jog.deadman_stops}")
        if jog.reason:
            lines.append(f"  {jog.reason}")
    else:
        lines.append("jog: no JogState yet (is the controller running?)")
    if bridge is not None:
        lines.append(f"bridge: {bridge.phase}" + (f" ({bridge.detail})" if bridge.detail else ""))
    if status is not None and status.msg_class in ("warning", "error"):
        lines.append(f"arm {status.msg_class}: {status.text or status.msg_code}")
    if teleop.status:
        lines.append(f"> {teleop.status}")
    return lines
