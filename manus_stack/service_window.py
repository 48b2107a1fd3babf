"""When a service's first process was alive in a recording: what a regression check
(:mod:`manus_stack.regression`) feeds and compares.

A lock-step recording holds one life of every core, from its start. A live recording
also holds the liveliness changes (``liveliness`` channel): when it shows the service's
process (its ``where/<service>/<host>/<pid>`` token) appear, only what was recorded while
that first process was alive is compared, from its token's appearance (services declare
it once they listen) to its disappearance (a restarted service is a new core).
"""

from __future__ import annotations

from collections.abc import Callable

from schemas.base import Message
from schemas.endpoints import LIVELINESS
from schemas.liveliness import LivelinessChange, TokenKind
from services.recorder.reading import Recording, decode

Window = tuple[int, int]
"""[first, last] log time [ns] of what a check feeds and compares."""

EVERYTHING: Window = (-(2**63), 2**63 - 1)


EARLY_OUTPUT_NS = 100_000_000
"""How long before its token a service's output may be recorded and still count as its
first process's (the token goes up once the service listens and answers, milliseconds
after its first answer, and the recorder hears liveliness on another path than data)."""


def service_window(
    recording: Recording, service: str, inputs: tuple[str, ...] = (), outputs: tuple[str, ...] = ()
) -> Window:
    """When the first process of ``service`` was alive, by the recorded liveliness
    changes of its ``where`` token (:data:`EVERYTHING` when the recording has none:
    lock-step recordings, or a recorder older than the liveliness channel).

    A service announces its token once it listens, so its first outputs can be recorded
    before the token: then the window starts at the last of its ``inputs`` (what its
    outputs answer: the joint states, for the planner also the perception frames)
    recorded before its first ``output``, not at the token.
    """
    start, end = _token_window(recording, service)
    if start == EVERYTHING[0] or not inputs or not outputs:
        return start, end
    first_out = next((r.log_ns for r in recording.messages(outputs)), None)
    if first_out is None or not start - EARLY_OUTPUT_NS <= first_out < start:
        return start, end  # none before the token, or a life the recording does not show
    trigger = start
    for rec in recording.messages(inputs):
        if rec.log_ns > first_out:
            break
        if rec.log_ns >= start - EARLY_OUTPUT_NS:
            trigger = rec.log_ns
    return min(trigger, start), end


def _token_window(recording: Recording, service: str) -> Window:
    """:func:`service_window` by the ``where`` token alone."""
    if not any(c.suffix == LIVELINESS for c in recording.info.channels.values()):
        return EVERYTHING
    start, end = EVERYTHING
    key: str | None = None
    for rec in recording.messages([LIVELINESS]):
        change = decode(rec)
        if not isinstance(change, LivelinessChange) or change.kind != TokenKind.WHERE:
            continue
        if key is None and change.alive and change.service == service:
            key, start = change.key, rec.log_ns
        elif key is not None and change.key == key and not change.alive:
            end = rec.log_ns
            break
    return start, end


ANSWER_LOOKBACK_NS = 1_000_000_000
"""How long before its token a service may have taken the input its first output answers
[ns] (a loaded service subscribes, then builds what it needs, then announces its token)."""


def from_first_answer(
    recording: Recording,
    window: Window,
    output: str,
    answered: Callable[[Message], int | None],
    inputs: str,
    key: Callable[[Message], int | None],
) -> Window:
    """``window`` from the input its first ``output`` answers, when that input was recorded
    before the window's start (at most :data:`ANSWER_LOOKBACK_NS` before).

    Args:
        recording: the recording.
        window: the service's window (:func:`service_window`).
        output: the output channel whose first message names what it answers.
        answered: that message -> the id of the input it answers (None: it names none).
        inputs: the input channel.
        key: an input message -> its id (the same kind of id).
    """
    if window[0] == EVERYTHING[0]:
        return window  # the whole recording: nothing before it
    first = next((r for r in recording.messages([output]) if r.log_ns >= window[0]), None)
    wanted = None if first is None else answered(decode(first))
    if wanted is None:
        return window
    start = window[0]
    for rec in recording.messages([inputs]):
        if rec.log_ns >= window[0]:
            break
        if rec.log_ns >= window[0] - ANSWER_LOOKBACK_NS and key(decode(rec)) == wanted:
            start = rec.log_ns
    return start, window[1]
