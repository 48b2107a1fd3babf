"""Replay-based regression checks: a recording's inputs through a service core, its
outputs compared with the recorded ones, bit for bit.

A check reads the recording in log-time order, feeds each input of the service to a
fresh core (as its shell would), and compares every output with the recorded message
of the same channel and rank, as encoded bytes. It reports the first difference (the
one caused by the earliest input): channel, rank, field path, both values. Outputs on
both sides are counted; one side running out is a difference too.

Inputs and outputs are those of the service's wiring map (:mod:`manus.wiring`), fed
through :meth:`~manus.wiring.Wiring.feed` as its live shell would: its subscriptions and
its queryables' mirrored requests in; its publications and mirrored replies out.

- ``planner``: joint states, perception frames, plan requests and scene updates in, plan
  and scene replies and the world model's updates out (``compute_ms`` is wall time and is
  not compared).
- ``controller``: the bridge's joint states, status and phase, the heartbeat, the jog
  stream (a ``jog`` payload that does not decode goes to its input's ``bad`` handler, as
  the live shell does), the scene, the liveliness tokens that vanished (as the controller
  took them: its ``controller/token_gone`` records) and the controller's query requests
  in; commands, feedback, results, the jog's state and the query replies out.

The recording must hold the service's whole life (a core starts empty): lock-step
recordings do (:mod:`manus_stack.recordings`); a live recording does if the recorder
started before the service (``manus up`` and ``manus demo`` start it first). A live
recording also holds the liveliness changes (``liveliness`` channel): when it shows the
service's process (its ``where/<service>/<host>/<pid>`` token) appear, only what was
recorded while that first process was alive is compared, from its token's appearance
(services declare it once they listen) to its disappearance (a restarted service is a
new core). Inputs are fed up to the service's last recorded output: whether it saw the
ones after it (as it stopped, or as the recorder stopped) the recording cannot tell. In
a live recording a query and a joint state that arrive together may be recorded in the
other order than the service saw them.
"""

from __future__ import annotations

import bisect
import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgpack

from manus.wiring import BAD_PAYLOAD
from manus_stack.difference import Difference, first_difference
from schemas import endpoints as ep
from schemas.base import Message
from schemas.endpoints import LIVELINESS
from schemas.jog import JogTaken
from schemas.liveliness import LivelinessChange, TokenGone, TokenKind
from schemas.planning import PlanReply
from schemas.state import JointState
from schemas.target import TargetTaken
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore
from services.controller.wiring import WIRING as CONTROLLER
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING as PLANNER
from services.recorder.errors import RecordingError
from services.recorder.reading import Recorded, Recording, decode


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one check.

    Attributes:
        service: the core checked.
        inputs: inputs fed to it.
        compared: outputs compared (identical ones included).
        recorded: recorded outputs.
        replayed: outputs the core produced.
        difference: the first difference (None: identical).
    """

    service: str
    inputs: int
    compared: int
    recorded: int
    replayed: int
    difference: Difference | None

    @property
    def ok(self) -> bool:
        """Every output identical."""
        return self.difference is None


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
    before the token: then the window starts at the last of its ``inputs`` (its clock:
    the joint states it answers) recorded before its first ``output``, not at the token.
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


class _Comparer:
    """Collects replayed outputs and compares them with the recorded ones per channel
    (those recorded within ``window``)."""

    def __init__(
        self, recording: Recording, outputs: tuple[str, ...], window: Window = EVERYTHING
    ) -> None:
        self.recorded: dict[str, list[Recorded]] = {s: [] for s in outputs}
        last: int | None = None
        for rec in recording.messages(outputs):
            if window[0] <= rec.log_ns <= window[1]:
                self.recorded[rec.suffix].append(rec)
                last = rec.log_ns if last is None else max(last, rec.log_ns)
        self.last_ns = window[1] if last is None else last
        """Log time of the last recorded output [ns] (none: the window's end, so that a
        service that answered nothing shows as a difference, not as an empty check)."""
        self.replayed: dict[str, list[tuple[int, bytes]]] = {s: [] for s in outputs}

    def add(self, suffix: str, payload: bytes, input_ns: int) -> None:
        self.replayed.setdefault(suffix, []).append((input_ns, payload))

    def result(self, service: str, inputs: int) -> CheckResult:
        best: Difference | None = None
        compared = 0
        for suffix in sorted(set(self.recorded) | set(self.replayed)):
            recs = self.recorded.get(suffix, [])
            reps = self.replayed.get(suffix, [])
            diff: Difference | None = None
            for rank in range(max(len(recs), len(reps))):
                rec = recs[rank] if rank < len(recs) else None
                rep = reps[rank] if rank < len(reps) else None
                if rec is not None and rep is not None:
                    compared += 1
                    if rec.payload == rep[1]:
                        continue
                    a, b = _plain(rec.payload), _plain(rep[1])
                    found = first_difference(a, b) or ("", a, b)
                    diff = Difference(suffix, rank, rep[0], found[0], found[1], found[2])
                elif rep is not None:
                    diff = Difference(suffix, rank, rep[0], "", None, _plain(rep[1]))
                elif rec is not None:
                    diff = Difference(suffix, rank, rec.log_ns, "", _plain(rec.payload), None)
                break
            if diff is not None and (best is None or diff.input_ns < best.input_ns):
                best = diff
        return CheckResult(
            service,
            inputs,
            compared,
            sum(map(len, self.recorded.values())),
            sum(map(len, self.replayed.values())),
            best,
        )


def _plain(payload: bytes) -> Any:
    try:
        return msgpack.unpackb(payload, raw=False, strict_map_key=False)
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
        return payload


def _inputs(
    recording: Recording, suffixes: tuple[str, ...], window: Window = EVERYTHING
) -> Iterator[tuple[Recorded, Message | None]]:
    """The inputs in order; None for a ``jog`` payload that does not decode (the live
    shell hands those to the controller as bad jogs)."""
    for rec in recording.messages(_present(recording, suffixes)):
        if window[0] <= rec.log_ns <= window[1]:
            try:
                yield rec, decode(rec)
            except RecordingError:
                if rec.suffix != ep.JOG:
                    raise
                yield rec, None


def _present(recording: Recording, suffixes: tuple[str, ...]) -> list[str]:
    have = {c.suffix for c in recording.info.channels.values()}
    return [s for s in suffixes if s in have]  # none: no input at all


def check_planner(path: str | Path, config: PlannerConfig | None = None) -> CheckResult:
    """Replay the planner's inputs through :class:`PlannerCore` (see the module docstring)."""
    recording = Recording(path)
    core = PlannerCore(config)
    window = service_window(
        recording,
        PLANNER.service,
        (ep.JOINTS,),
        PLANNER.output_suffixes,  # its clock input
    )
    outputs = PLANNER.output_suffixes
    cmp = _Comparer(recording, outputs, window)
    window = (window[0], cmp.last_ns)
    recorded_ms = {s: [_plain(r.payload) for r in cmp.recorded[s]] for s in outputs}
    inputs = 0
    for rec, msg in _inputs(recording, PLANNER.input_suffixes, window):
        inputs += 1
        if msg is None:  # a bad jog payload: not the planner's
            continue
        for suffix, out in PLANNER.feed(core, rec.suffix, msg, rec.log_ns):
            sent = out
            if isinstance(out, PlanReply):  # compute_ms is wall time: not compared
                rank = len(cmp.replayed[suffix])
                recorded = recorded_ms[suffix]
                if rank < len(recorded) and isinstance(recorded[rank], dict):
                    ms = recorded[rank].get("compute_ms", 0.0)
                    sent = dataclasses.replace(out, compute_ms=ms if isinstance(ms, float) else 0.0)
            cmp.add(suffix, sent.encode(), rec.log_ns)
    return cmp.result(PLANNER.service, inputs)


def check_controller(path: str | Path, config: ControllerConfig | None = None) -> CheckResult:
    """Replay the controller's inputs through :class:`ControllerCore` (module docstring)."""
    recording = Recording(path)
    core = ControllerCore(config)
    window = _controller_window(recording)
    cmp = _Comparer(recording, CONTROLLER.output_suffixes, window)
    window = (window[0], cmp.last_ns)
    inputs = 0
    for rec, msg in _controller_inputs(recording, window):
        inputs += 1
        t = rec.log_ns
        if isinstance(msg, JogTaken):  # where the controller took it (see below)
            taken = msg.command
            outputs = (
                CONTROLLER.feed(core, ep.JOG, taken, t)
                if taken is not None
                else CONTROLLER.feed_bad(core, ep.JOG, msg.error, t)
            )
        elif isinstance(msg, TargetTaken):  # the same for a tracker's frames
            frame = msg.target
            outputs = (
                CONTROLLER.feed(core, ep.TARGET, frame, t)
                if frame is not None
                else CONTROLLER.feed_bad(core, ep.TARGET, msg.error, t)
            )
        elif isinstance(msg, TokenGone):  # a token is no sample: its record, in place
            outputs = CONTROLLER.feed_token_gone(core, msg.service, t)
        elif msg is None:
            outputs = CONTROLLER.feed_bad(core, rec.suffix, BAD_PAYLOAD, t)
        else:
            outputs = CONTROLLER.feed(core, rec.suffix, msg, t)
        for suffix, out_msg in outputs:
            cmp.add(suffix, out_msg.encode(), rec.log_ns)
    return cmp.result(CONTROLLER.service, inputs)


def _controller_window(recording: Recording) -> Window:
    """The controller's window (:func:`service_window`): from the joint state its first
    command answers; and from its first record of a taken input (a tracker's frame, a jog
    command) before any joint state, when that comes first: a tracker publishing before the
    controller listens is taken at once, and every frame taken shapes its prediction."""
    start, end = service_window(recording, CONTROLLER.service, (ep.JOINTS,), (ep.JOINT_VELOCITY,))
    if start == EVERYTHING[0]:
        return start, end
    taken = (ep.TARGET_TAKEN, ep.JOG_TAKEN)
    for rec in recording.messages(taken):
        if rec.log_ns >= start:
            break
        msg = decode(rec)
        if rec.log_ns >= start - EARLY_OUTPUT_NS and getattr(msg, "after_seq", 0) < 0:
            return rec.log_ns, end
    return start, end


def _controller_inputs(
    recording: Recording, window: Window
) -> list[tuple[Recorded, Message | None]]:
    """The controller's inputs in the order it saw them.

    The jog stream and the joint states come from two publishers, so a recorder may log a
    command and a joint state that arrived together in the other order than the controller
    saw them. The controller publishes each command it takes as a
    :class:`~schemas.jog.JogTaken` saying after which joint state it came: when the
    recording holds those, each is fed (as the command it carries) after that joint state
    and before the next, at its log time within that span, instead of the raw stream; a
    tracker's frames likewise (:class:`~schemas.target.TargetTaken`).
    A vanished liveliness token is no sample at all: the controller's
    :class:`~schemas.liveliness.TokenGone` records are placed the same way.
    """
    have = {c.suffix for c in recording.info.channels.values()}
    records = tuple(s for s in (ep.JOG_TAKEN, ep.TARGET_TAKEN, ep.TOKEN_GONE) if s in have)
    suffixes = CONTROLLER.input_suffixes
    for record, raw in ((ep.JOG_TAKEN, ep.JOG), (ep.TARGET_TAKEN, ep.TARGET)):
        if record in have:
            suffixes = tuple(s for s in suffixes if s != raw)
    base = list(_inputs(recording, suffixes, window))
    if not records:
        return base
    times = [rec.log_ns for rec, _ in base]
    states = [i for i, (_, m) in enumerate(base) if isinstance(m, JointState)]
    at_seq = {m.seq: i for i, (_, m) in enumerate(base) if isinstance(m, JointState)}
    placed: list[tuple[int, int, Recorded, Message | None]] = []
    for order, (rec, taken) in enumerate(_inputs(recording, records, window)):
        assert isinstance(taken, JogTaken | TargetTaken | TokenGone)
        pos = bisect.bisect_right(times, rec.log_ns)
        after = at_seq.get(taken.after_seq)
        if after is not None:  # within (that joint state, the next one]
            nxt = next((i for i in states if i > after), len(base))
            pos = min(max(pos, after + 1), nxt)
        elif taken.after_seq < 0 and states:  # before any joint state
            pos = min(pos, states[0])
        placed.append((pos, order, rec, taken))
    out: list[tuple[Recorded, Message | None]] = []
    j = 0
    placed.sort(key=lambda p: (p[0], p[1]))
    for i, item in enumerate(base):
        while j < len(placed) and placed[j][0] <= i:
            out.append((placed[j][2], placed[j][3]))
            j += 1
        out.append(item)
    out += [(p[2], p[3]) for p in placed[j:]]
    return out


CHECKS: dict[str, Callable[[str | Path], CheckResult]] = {
    PLANNER.service: check_planner,
    CONTROLLER.service: check_controller,
}
"""Service -> its check."""
