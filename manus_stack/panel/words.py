"""What the panel tells the person in the chair: each kind of trouble in one plain sentence.

The stack reports why a task was refused or failed for engineers ("step 1 (pose): planner
refused (unreachable): ..."). The person using the panel needs to know what happened and
what to do, in words: "The cup is out of reach." So every report is first sorted into a
:class:`Trouble` (a typed kind), and each kind has one sentence (:data:`SENTENCES`); the
report itself stays available as the details, for a helper.

Where the reports come from:

- a refused submission (``SubmitReply``): :func:`refusal_trouble`;
- a failed or paused task (``TaskEvent.reason``): :func:`task_trouble`;
- the jog (``JogState.reason``): :func:`jog_trouble`.

The sequencer's task events carry their cause in words only (``TaskEvent.reason``, the
failing service's own words behind the step's label), so :func:`task_trouble` and
:func:`refusal_trouble` read those words, in this one place, against the fixed phrases the
sequencer and the planner write (``tests/test_panel_words.py`` checks them against
reasons the real cores produce). The planner's refusals carry their typed kind
(``PlanErrorReason``) in the sequencer's validation errors, and that is what is read there.
"""

from __future__ import annotations

import re
from enum import StrEnum

from schemas.planning import PlanErrorReason
from schemas.sequencing import SubmitReply


class Trouble(StrEnum):
    """A kind of trouble the panel tells the user about, each with one sentence."""

    OUT_OF_REACH = "out_of_reach"
    """the planner cannot reach it (outside the workspace, a joint limit, a singularity)"""
    TOO_CLOSE = "too_close"
    """the arm would come too close to the person, the chair or an object"""
    FOLDED = "folded"
    """the arm is folded: a task that moves it needs it unfolded first"""
    STOPPED = "stopped"
    """the emergency stop is on"""
    ARM_ERROR = "arm_error"
    """the arm reports an error"""
    NOT_READY = "not_ready"
    """the arm is not ready (the bridge is starting or folding; no joint state)"""
    HELD_STOPPED = "held_stopped"
    """the bridge holds the arm stopped after a fault (phase ``stopped``: a fold's deadman,
    the arm's frames lost and back) until it is cleared; releasing an e-stop clears it"""
    BUSY = "busy"
    """another task runs"""
    PARTS_MISSING = "parts_missing"
    """a service of the stack is not running"""
    LINK_LOST = "link_lost"
    """the link to the arm was lost (joint states, heartbeat, a service's token)"""
    TOOK_OVER = "took_over"
    """the user moved the arm by hand: the task is paused"""
    CANCELLED = "cancelled"
    """the task was cancelled"""
    TIMED_OUT = "timed_out"
    """a step took too long"""
    NOT_SET_UP = "not_set_up"
    """the button's task is not set up on this arm"""
    NO_CONNECTION = "no_connection"
    """the panel lost its connection to the stack (or the page to the panel)"""
    JOG_LATE = "jog_late"
    """the hand control stopped: its commands came too late (the jog's deadman)"""
    JOG_REFUSED = "jog_refused"
    """the hand control cannot move the arm now"""
    RELEASE_FIRST = "release_first"
    """the hand control stopped: let go of the buttons before moving again"""
    UNKNOWN = "unknown"
    """anything else"""


SENTENCES: dict[Trouble, str] = {
    Trouble.OUT_OF_REACH: "{About} is out of reach.",
    Trouble.TOO_CLOSE: "The arm would come too close to you or to something near you.",
    Trouble.FOLDED: "The arm is folded. Press Unfold first.",
    Trouble.STOPPED: "STOP is on. Press Release stop when it is safe to move.",
    Trouble.ARM_ERROR: "The arm reports a fault. Ask your helper to check it.",
    Trouble.NOT_READY: "The arm is not ready yet. Try again in a moment.",
    Trouble.HELD_STOPPED: "The arm stopped itself after a fault. When it is safe, press STOP, "
    "then Release stop.",
    Trouble.BUSY: "The arm is busy with another task. Wait for it, or press Cancel.",
    Trouble.PARTS_MISSING: "Part of the arm's system is not running. Ask your helper.",
    Trouble.LINK_LOST: "The connection to the arm was lost, so the arm stopped.",
    Trouble.TOOK_OVER: "Paused because you moved the arm. Press Resume to go on.",
    Trouble.CANCELLED: "The task was cancelled.",
    Trouble.TIMED_OUT: "The arm took too long, so it stopped.",
    Trouble.NOT_SET_UP: "{About} is not set up on this arm yet.",
    Trouble.NO_CONNECTION: "The panel has lost its connection to the arm.",
    Trouble.JOG_LATE: "The arm stopped: the signal from the button came too late. "
    "Let go, then press again.",
    Trouble.JOG_REFUSED: "The arm cannot be moved by hand right now.",
    Trouble.RELEASE_FIRST: "Let go of the button, then press again.",
    Trouble.UNKNOWN: "Something went wrong and the arm stopped. Ask your helper.",
}
"""One sentence per trouble; ``{About}`` is what the task is about, capitalised."""


def sentence(trouble: Trouble, about: str = "") -> str:
    """The sentence for ``trouble``; ``about`` names what the task is about ("the cup")."""
    thing = about or "That place"
    return SENTENCES[trouble].replace("{About}", thing[:1].upper() + thing[1:])


_PLAN = re.compile(r"planner refused \((\w+)\)")
"""A validation error of the sequencer: the planner's typed refusal in parentheses."""

PLAN_TROUBLES: dict[str, Trouble] = {
    PlanErrorReason.UNREACHABLE: Trouble.OUT_OF_REACH,
    PlanErrorReason.JOINT_LIMIT: Trouble.OUT_OF_REACH,
    PlanErrorReason.SINGULAR: Trouble.OUT_OF_REACH,
    PlanErrorReason.BRANCH: Trouble.OUT_OF_REACH,
    PlanErrorReason.SPEED_LIMIT: Trouble.OUT_OF_REACH,
    PlanErrorReason.COLLISION: Trouble.TOO_CLOSE,
    PlanErrorReason.NO_STATE: Trouble.NOT_READY,
}
"""The planner's typed refusals (``PlanErrorReason``) -> trouble (the rest: unknown)."""

_PHASES: tuple[tuple[str, Trouble], ...] = (
    ("estopped", Trouble.STOPPED),
    ("arm_error", Trouble.ARM_ERROR),
    ("the arm reports an error", Trouble.ARM_ERROR),
    ("stopped: arm error", Trouble.ARM_ERROR),
    ("phase 'stopped'", Trouble.HELD_STOPPED),
    ("bridge phase stopped", Trouble.HELD_STOPPED),
)
"""What the controller names when it stops or refuses a jog that has a trouble of its
own (a stop keeps its words while the commands it holds back are counted)."""

_PHRASES: tuple[tuple[str, Trouble], ...] = (
    ("the arm is folded there", Trouble.FOLDED),
    ("phase stopped", Trouble.HELD_STOPPED),  # before the fault that stopped it: it is held
    ("(stopped", Trouble.HELD_STOPPED),
    ("e-stop", Trouble.STOPPED),
    ("phase estopped", Trouble.STOPPED),
    ("(estopped)", Trouble.STOPPED),
    ("phase arm_error", Trouble.ARM_ERROR),
    ("(arm_error)", Trouble.ARM_ERROR),
    ("user took over", Trouble.TOOK_OVER),
    ("cancelled by request", Trouble.CANCELLED),
    ("lost the supervisor's heartbeat", Trouble.LINK_LOST),
    ("liveliness token went", Trouble.LINK_LOST),
    ("no joint states from the arm", Trouble.LINK_LOST),
    ("is gone (its liveliness token vanished)", Trouble.PARTS_MISSING),
    ("required service(s) not running", Trouble.PARTS_MISSING),
    ("busy: task", Trouble.BUSY),
    ("the user is jogging", Trouble.TOOK_OVER),
    ("collision", Trouble.TOO_CLOSE),
    ("would bring the", Trouble.TOO_CLOSE),
    ("no valid joint state", Trouble.NOT_READY),
    ("the bridge is not running", Trouble.NOT_READY),
    ("can_bridge: phase", Trouble.NOT_READY),
    ("did not complete within", Trouble.TIMED_OUT),
    ("in time (goal deadline passed)", Trouble.TIMED_OUT),
)
"""Fixed phrases of the sequencer's reports -> trouble, the first that matches wins
(order: the specific before the general)."""


def task_trouble(reason: str) -> Trouble:
    """The trouble a task's failure (or pause) reason reports (``TaskEvent.reason``)."""
    match = _PLAN.search(reason)
    if match is not None and match.group(1) in PLAN_TROUBLES:
        folded = "the arm is folded there" in reason
        return Trouble.FOLDED if folded else PLAN_TROUBLES[match.group(1)]
    for phrase, trouble in _PHRASES:
        if phrase in reason:
            return trouble
    if "planner refused" in reason:  # at run time the planner's kind is not in the words
        return Trouble.OUT_OF_REACH
    return Trouble.UNKNOWN


def refusal_trouble(reply: SubmitReply) -> Trouble:
    """The trouble a refused submission reports: the first of its errors that says one
    (a folded arm before everything else: it explains the others)."""
    troubles = [task_trouble(error) for error in reply.errors]
    if Trouble.FOLDED in troubles:
        return Trouble.FOLDED
    return next((t for t in troubles if t is not Trouble.UNKNOWN), Trouble.UNKNOWN)


def jog_trouble(reason: str, refused: bool) -> Trouble | None:
    """The trouble of the jog's state words (``JogState.reason``; None: nothing to say).

    Args:
        reason: the controller's words for the jog's state.
        refused: the controller refused a command since the last state (its count grew).
    """
    if reason.startswith("stopped: deadman"):
        return Trouble.JOG_LATE
    for phase, trouble in _PHASES:
        if phase in reason:
            return trouble
    if refused and "release the controls" in reason:
        return Trouble.RELEASE_FIRST
    if refused:
        return Trouble.JOG_REFUSED
    return None
