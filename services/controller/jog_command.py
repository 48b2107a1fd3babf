"""A jog command checked and turned into SI speeds at the speed level in use.

:func:`resolve` refuses (:class:`JogError`, naming the field, value and limit) a command
that is not finite, outside -1..1 (unitless), above the top level's caps (SI), of an
unknown kind, frame or units, or with values that do not belong to its kind; else it
returns the speeds (:class:`~services.controller.jog_law.JogTarget`): unitless
deflections scaled to the caps times level / levels, SI speeds limited to that, by one
factor for a twist so that its direction is kept. A command the level's caps scale down
is never changed silently: the target carries the caps that did it, and the jog state
reports them (``JogState.limits``, kind ``speed_cap``) while they hold. The fields each
kind uses are :data:`schemas.jog.KIND_FIELDS`, the table the JSON Schema shows.
"""

from __future__ import annotations

import math

from manus.errors import ManusError
from schemas.jog import (
    KIND_FIELDS,
    SPEED_FIELDS,
    JogCommand,
    JogFrame,
    JogKind,
    JogUnits,
    LimitKind,
)
from services.controller.jog_config import JogConfig
from services.controller.jog_law import JogTarget
from services.controller.jog_limits import Slowdown

_TOLERANCE = 1e-9
"""Relative slack of the range checks (a value at the cap is allowed)."""


class JogError(ManusError, ValueError):
    """A jog command that cannot be executed (the message names the field, value, limit)."""


def _norm(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values))


def _check_values(cmd: JogCommand) -> None:
    for name, enum in (("kind", JogKind), ("units", JogUnits), ("frame", JogFrame)):
        value = getattr(cmd, name)
        allowed = [m.value for m in enum]
        if value not in allowed:
            raise JogError(f"`{name}` {value!r} is not one of {allowed}")
    for name, size in (("linear", 3), ("angular", 3), ("joints", 6)):
        values = getattr(cmd, name)
        if len(values) != size:
            raise JogError(f"`{name}` must hold {size} values, got {len(values)}")
    scalars = [("gripper", cmd.gripper), ("pour", cmd.pour)]
    named = [
        (f"{n}[{i}]", v)
        for n in ("linear", "angular", "joints")
        for i, v in enumerate(getattr(cmd, n))
    ]
    for name, value in named + scalars:
        if not (isinstance(value, int | float) and math.isfinite(value)):
            raise JogError(f"`{name}` = {value!r} is not a finite number")
        if cmd.units == JogUnits.UNITLESS and abs(value) > 1.0 + _TOLERANCE:
            raise JogError(f"`{name}` = {value!r} is outside -1..1 (unitless deflection)")
    uses = KIND_FIELDS.get(cmd.kind, ())
    if cmd.kind != JogKind.STOP:
        for name in (*SPEED_FIELDS, "drink"):
            value = getattr(cmd, name)
            if name not in uses and (any(value) if isinstance(value, list) else value):
                raise JogError(
                    f"a `{cmd.kind}` command carries no `{name}` (it uses {', '.join(uses)})"
                )
    if cmd.drink and (cmd.angular[0] or cmd.angular[1]):
        raise JogError(
            f"drink mode holds the cup level: `angular[0]` = {cmd.angular[0]!r} and "
            f"`angular[1]` = {cmd.angular[1]!r} must be 0 (only the yaw, `angular[2]`, turns)"
        )
    if cmd.pour and not cmd.drink:
        raise JogError(f"`pour` = {cmd.pour!r} needs drink mode (`drink` true)")


def _capped(name: str, scale: float) -> Slowdown:
    return Slowdown(scale, LimitKind.SPEED_CAP, name, 0.0, f"the level's {name} speed cap")


def resolve(cmd: JogCommand, level: int, cfg: JogConfig) -> JogTarget | None:
    """The SI speeds a command asks for at speed level ``level`` (None: stop).

    Raises:
        JogError: the command is malformed or out of range (module docstring).
    """
    _check_values(cmd)
    if cmd.kind == JogKind.STOP:
        return None
    share = cfg.share(level)
    lin, ang, pour = list(cmd.linear), list(cmd.angular), cmd.pour
    joints, grip = list(cmd.joints), cmd.gripper
    if cmd.units == JogUnits.UNITLESS:  # a deflection of the level's share of the caps
        lin = [v * cfg.max_linear * share for v in lin]
        ang = [v * cfg.max_angular * share for v in ang]
        pour *= cfg.max_angular * share
        joints = [v * cfg.max_joint * share for v in joints]
        grip *= cfg.max_gripper * share
    else:
        for name, size, cap, unit, k in (
            ("linear", _norm(lin), cfg.max_linear, "mm/s", 1000.0),
            ("angular", _norm(ang), cfg.max_angular, "deg/s", 180.0 / math.pi),
            ("pour", abs(pour), cfg.max_angular, "deg/s", 180.0 / math.pi),
            ("joints", max(map(abs, joints)), cfg.max_joint, "deg/s", 180.0 / math.pi),
            ("gripper", abs(grip), cfg.max_gripper, "mm/s", 1000.0),
        ):
            if size > cap * (1.0 + _TOLERANCE):
                raise JogError(
                    f"`{name}` speed {size * k:.1f} {unit} is above the cap {cap * k:.1f} {unit}"
                )
    # One factor for a twist (its direction, and a straight line, are kept), reported.
    sizes = (
        ("linear", _norm(lin), cfg.max_linear),
        ("angular", _norm(ang) + abs(pour), cfg.max_angular),
        ("joints", max(map(abs, joints)), cfg.max_joint),
    )
    f = min([1.0] + [cap * share / size for _, size, cap in sizes if size > 0.0])
    binding = [name for name, size, cap in sizes if size > 0.0 and cap * share / size == f]
    caps = [_capped(binding[0], f)] if f < 1.0 - _TOLERANCE else []  # not a rounding
    top = cfg.max_gripper * share
    if abs(grip) > top * (1.0 + _TOLERANCE):
        caps.append(_capped("gripper", top / abs(grip)))
    grip = max(-top, min(top, grip))
    target = JogTarget(
        cmd.kind,
        cmd.frame,
        tuple(v * f for v in lin),
        tuple(v * f for v in ang),
        tuple(v * f for v in joints),
        grip,
        cmd.drink,
        pour * f,
        tuple(caps),
    )
    if not target.arm_moves and target.gripper == 0.0:
        return None
    return target
