"""The jog's state as a client reads it: ``JogState`` from the jog's typed limits and stop.

What holds a running jog back is a list of :class:`~.jog_limits.Slowdown` (the level's
caps, the jog law's motors' cap or zone, the collision guard's verdict:
:func:`guard_limit`); each becomes a :class:`~schemas.jog.JogLimit` and the state's
``scale`` is the product of the arm's. The words (``reason``) are made from the same
typed values, without the numbers that change every cycle, so they stay the same while
the state does (:func:`jog_reason`).
"""

from __future__ import annotations

from manus.clearance import Clearance
from manus.config import ArmConfig, is_folded
from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from schemas.control import EndCause
from schemas.jog import JogCaps, JogLimit, JogRunState, JogState, LimitKind
from schemas.state import JointState
from services.controller.command_source import End
from services.controller.guard import Verdict
from services.controller.jog_law import JogTarget
from services.controller.jog_limits import Slowdown


def guard_limit(verdict: Verdict) -> Slowdown | None:
    """The collision guard's verdict on a jog command as a limit (None: it did nothing)."""
    found: Clearance | None = verdict.near
    if verdict.scale >= 1.0 or found is None:
        return None
    check = found.check
    zone = check.cls == "zone"
    words = (
        f"the collision guard: {check.body} at the zone {check.other}"
        if zone
        else f"the collision guard: {check.body} near {check.other} ({check.cls}: "
        f"keeps {check.required * 1e3:.0f} mm)"
    )
    kind = LimitKind.ZONE if zone else LimitKind.COLLISION
    return Slowdown(verdict.scale, kind, check.other, 0.0, words, check.body, float(found.distance))


def jog_reason(stopped: End | None, cause: EndCause | None, limits: list[Slowdown]) -> str:
    """The state in words: the stop and what re-arms it, the tightest limit, a release."""
    if stopped is not None:
        return f"stopped: {stopped.reason}; release the controls (a zero command) to jog again"
    if limits:
        tight = min(limits, key=lambda lim: lim.scale)
        return f"{'stopped' if tight.scale <= 0.0 else 'slowed'} by {tight.words}"
    return "released" if cause == EndCause.RELEASED else ""


def jog_state(
    js: JointState,
    seq: int,
    *,
    target: JogTarget | None,
    stopped: End | None,
    cause: EndCause | None,
    limits: list[Slowdown],
    reason: str,
    level: tuple[int, int],
    caps: JogCaps,
    counts: tuple[int, int, int],
    arm: ArmConfig,
) -> JogState:
    """The JogState answering ``js``.

    Args:
        js: the joint state answered.
        seq: the state's number.
        target: the speeds being executed (None: none).
        stopped: the stop in force (None: armed).
        cause: why the jog last stopped (None: never).
        limits: what holds the running jog back this cycle.
        reason: the same in words (:func:`jog_reason`).
        level: the speed level in use and the number of levels.
        caps: the caps at that level.
        counts: the newest command's seq, the refusals, the deadman stops.
        arm: the arm model.
    """
    T = fk(js.position, arm)
    command_seq, refused, deadman_stops = counts
    state = (
        JogRunState.RUNNING
        if target is not None
        else JogRunState.STOPPED
        if stopped is not None
        else JogRunState.IDLE
    )
    scale = 1.0
    for lim in limits:
        if lim.object != "gripper":  # the gripper's cap holds back the gripper alone
            scale *= lim.scale
    return JogState(
        stamp_ns=js.stamp_ns,
        seq=seq,
        state=state,
        active=target is not None,
        cause=cause or "",
        kind=target.kind if target is not None else "",
        frame=target.frame if target is not None else "",
        drink=target.drink if target is not None else False,
        level=level[0],
        levels=level[1],
        caps=caps,
        scale=min(1.0, max(0.0, scale)),
        limits=[_message(lim) for lim in limits],
        reason=reason,
        command_seq=command_seq,
        refused=refused,
        deadman_stops=deadman_stops,
        folded=is_folded(js.position),
        actual_xyz=[float(v) for v in T[:3, 3]],
        actual_ypr=[float(v) for v in matrix_to_ypr(T[:3, :3])],
    )


def _message(lim: Slowdown) -> JogLimit:
    return JogLimit(
        kind=lim.kind,
        object=lim.object,
        scale=min(1.0, max(0.0, lim.scale)),
        body=lim.body,
        distance=lim.distance,
        angle=lim.angle,
    )
