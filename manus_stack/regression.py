"""Replay-based regression checks: a recording's inputs through a service core, its
outputs compared with the recorded ones (:mod:`manus_stack.comparison`): structure,
strings and integers (every command count) exactly, floats within a stated tolerance
(NumPy's vectorised maths, OpenBLAS and glibc's libm round differently on different
CPUs; on one machine the outputs are the same bit for bit).

A check reads the recording in log-time order, feeds each input of the service to a
fresh core (as its shell would), and compares every output with the recorded message
of the same channel and rank. It reports the first difference (the one caused by the
earliest input): channel, rank, field path, both values. Outputs on both sides are
counted; one side running out is a difference too.

Inputs and outputs are those of the service's wiring map (:mod:`manus.wiring`), fed
through :meth:`~manus.wiring.Wiring.feed` as its live shell would: its subscriptions and
its queryables' mirrored requests in; its publications and mirrored replies out.

- ``planner``: joint states, perception frames, plan requests, scene updates and attach
  requests in, plan, scene and attach replies and the world model's updates out
  (``compute_ms`` is wall time and is not compared; the scene it announces is compared
  by its changes, not by which joint state repeated it: :func:`_changes`).
- ``controller``: the bridge's joint states, status and phase, the heartbeat, the jog
  stream (a ``jog`` payload that does not decode goes to its input's ``bad`` handler, as
  the live shell does), the scene, the world model's updates (what the arm holds), the
  liveliness tokens that vanished (as the controller
  took them: its ``controller/token_gone`` records) and the controller's query requests
  in; commands, feedback, results, the jog's state and the query replies out.

The recording must hold the service's whole life (a core starts empty): lock-step
recordings do (:mod:`manus_stack.recordings`); a live recording does if the recorder
started before the service (``manus up`` and ``manus demo`` start it first). Of a live
recording, only the life of the service's first process is compared
(:mod:`manus_stack.service_window`). Inputs are fed up to the service's last recorded
output: whether it saw the ones after it (as it stopped, or as the recorder stopped) the
recording cannot tell. In a live recording a query and a joint state that arrive
together may be recorded in the other order than the service saw them: the controller
publishes where it took each (``controller/query_taken``, ``controller/jog_taken``,
``controller/token_gone``) and is fed in that order; the planner plans from the newest
joint state it has, so the same reordering can still change a live planner check.
"""

from __future__ import annotations

import bisect
import dataclasses
from collections.abc import Callable, Iterator
from pathlib import Path

from manus.wiring import BAD_PAYLOAD
from manus_stack.comparison import CPU_ROUNDING, CheckResult, Comparer, plain
from manus_stack.service_window import (
    EARLY_OUTPUT_NS,
    EVERYTHING,
    Window,
    from_first_answer,
    service_window,
)
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import JointVelocityCommand
from schemas.control import QueryTaken
from schemas.endpoints import TRACE_PARTS
from schemas.jog import JogTaken
from schemas.liveliness import TokenGone
from schemas.objects import Perception, WorldUpdate
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


def _recorded_outputs(
    recording: Recording, outputs: tuple[str, ...], window: Window
) -> tuple[dict[str, list[Recorded]], int]:
    """The outputs recorded within ``window`` per channel, and the log time [ns] of the
    last one (none: the window's end, so that a service that answered nothing shows as a
    difference, not as an empty check)."""
    recorded: dict[str, list[Recorded]] = {s: [] for s in outputs}
    last: int | None = None
    for rec in recording.messages(outputs):
        if window[0] <= rec.log_ns <= window[1]:
            recorded[rec.suffix].append(rec)
            last = rec.log_ns if last is None else max(last, rec.log_ns)
    return recorded, window[1] if last is None else last


def _inputs(
    recording: Recording, suffixes: tuple[str, ...], window: Window
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


def _changes(announced: list[Recorded]) -> list[Recorded]:
    """The planner's scene announcements where the scene changed: each repeat of the one
    before is left out. The planner repeats the scene in use on joint states (every
    ``scene_every_ms`` of their stamps since it last did), so which joint state a repeat
    follows depends on every joint state the live planner took: one it did not take (a
    loaded computer) moves every repeat after it, while the recording holds them all
    (seen: "planner/scene_state #37: the replay produced nothing"). The scenes, and when
    an update replaced one, are still compared."""
    kept: list[Recorded] = []
    for rec in announced:
        if not kept or rec.payload != kept[-1].payload:
            kept.append(rec)
    return kept


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
        # What its first outputs answer: a joint state (the scene in use) or a
        # perception frame (the world model), either maybe before its token.
        (ep.JOINTS, ep.PERCEPTION),
        PLANNER.output_suffixes,
    )
    # a loaded planner may take a camera frame before the recorder hears its token: its
    # first world model update names the frame (its stamp)
    window = from_first_answer(
        recording,
        window,
        ep.OBJECTS,
        lambda m: m.stamp_ns if isinstance(m, WorldUpdate) else None,
        ep.PERCEPTION,
        lambda m: m.stamp_ns if isinstance(m, Perception) else None,
    )
    outputs = PLANNER.output_suffixes
    recorded, last_ns = _recorded_outputs(recording, outputs, window)
    recorded[ep.SCENE_STATE] = _changes(recorded[ep.SCENE_STATE])
    cmp = Comparer(recorded, last_ns, CPU_ROUNDING)
    window = (window[0], last_ns)
    recorded_ms = {s: [plain(r.payload) for r in recorded[s]] for s in outputs}
    inputs = 0
    scene = b""
    for rec, msg in _inputs(recording, PLANNER.input_suffixes, window):
        inputs += 1
        if msg is None:  # a bad jog payload: not the planner's
            continue
        for suffix, out in PLANNER.feed(core, rec.suffix, msg, rec.log_ns):
            if suffix == ep.SCENE_STATE:
                if out.encode() == scene:
                    continue  # the same scene announced again (_changes)
                scene = out.encode()
            sent = out
            if isinstance(out, PlanReply):  # compute_ms is wall time: not compared
                rank = len(cmp.replayed[suffix])
                mine = recorded_ms[suffix]
                if rank < len(mine) and isinstance(mine[rank], dict):
                    ms = mine[rank].get("compute_ms", 0.0)
                    sent = dataclasses.replace(out, compute_ms=ms if isinstance(ms, float) else 0.0)
            cmp.add(suffix, sent.encode(), rec.log_ns)
    return cmp.result(PLANNER.service, inputs)


def check_controller(path: str | Path, config: ControllerConfig | None = None) -> CheckResult:
    """Replay the controller's inputs through :class:`ControllerCore` (module docstring)."""
    recording = Recording(path)
    core = ControllerCore(config)
    window = service_window(
        recording,
        CONTROLLER.service,
        (ep.JOINTS,),
        CONTROLLER.output_suffixes,  # its clock
    )
    window = _from_first_taken(recording, _from_first_answered(recording, window))
    recorded, last_ns = _recorded_outputs(recording, CONTROLLER.output_suffixes, window)
    cmp = Comparer(recorded, last_ns, CPU_ROUNDING)  # its counts exactly: integers
    window = (window[0], last_ns)
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


def _from_first_answered(recording: Recording, window: Window) -> Window:
    """``window`` from the joint state the controller's first command answers (its
    ``ref_seq``): a loaded controller may take it before the recorder hears its token."""
    return from_first_answer(
        recording,
        window,
        ep.JOINT_VELOCITY,
        lambda m: m.ref_seq if isinstance(m, JointVelocityCommand) else None,
        ep.JOINTS,
        lambda m: m.seq if isinstance(m, JointState) else None,
    )


def _from_first_taken(recording: Recording, window: Window) -> Window:
    """``window`` from the controller's first record of a taken input (a tracker's frame,
    a jog command) before any joint state, when that comes before the window's start (at
    most :data:`~manus_stack.service_window.EARLY_OUTPUT_NS` before): a tracker publishing
    before the controller listens is taken at once, and every frame taken shapes its
    prediction."""
    start, end = window
    if start == EVERYTHING[0]:
        return window
    for rec in recording.messages((ep.TARGET_TAKEN, ep.JOG_TAKEN)):
        if rec.log_ns >= start:
            break
        msg = decode(rec)
        if rec.log_ns >= start - EARLY_OUTPUT_NS and getattr(msg, "after_seq", 0) < 0:
            return rec.log_ns, end
    return window


def _controller_inputs(
    recording: Recording, window: Window
) -> list[tuple[Recorded, Message | None]]:
    """The controller's inputs in the order it saw them.

    The jog stream, the queries and the joint states come from different publishers, so a
    recorder may log a command or a query and a joint state that arrived together in the
    other order than the controller saw them. The controller publishes each jog command it
    takes as a :class:`~schemas.jog.JogTaken` and each query as a
    :class:`~schemas.control.QueryTaken`, saying after which joint state it came: when the
    recording holds those, each command (the one the record carries) or query (the
    mirrored request of the same rank on that queryable) is fed after that joint state
    and before the next, at its log time within that span; a tracker's frames likewise
    (:class:`~schemas.target.TargetTaken`). A vanished liveliness token is no sample at
    all: the controller's :class:`~schemas.liveliness.TokenGone` records are placed the
    same way.
    """
    have = {c.suffix for c in recording.info.channels.values()}
    taken = (ep.JOG_TAKEN, ep.TARGET_TAKEN, ep.TOKEN_GONE, ep.QUERY_TAKEN)
    records = tuple(s for s in taken if s in have)
    raw_of = ((ep.JOG_TAKEN, ep.JOG), (ep.TARGET_TAKEN, ep.TARGET))
    moved: set[str] = {raw for record, raw in raw_of if record in have}
    requests = {a.endpoint.trace(TRACE_PARTS[0]): a.endpoint.suffix for a in CONTROLLER.answers}
    if ep.QUERY_TAKEN in have:
        moved |= set(requests)
    everything = list(_inputs(recording, CONTROLLER.input_suffixes, window))
    base = [item for item in everything if item[0].suffix not in moved]
    if not records:
        return base
    # each query's records in order, to pair with its mirrored requests by rank
    taken_at: dict[str, list[int]] = {}
    placeable: list[tuple[Recorded, Message | None, int | None]] = []
    for rec, msg in _inputs(recording, records, window):
        if isinstance(msg, QueryTaken):
            taken_at.setdefault(msg.query, []).append(msg.after_seq)
        else:
            assert isinstance(msg, JogTaken | TargetTaken | TokenGone)
            placeable.append((rec, msg, msg.after_seq))
    rank: dict[str, int] = {}
    for rec, msg in everything:
        query = requests.get(rec.suffix)
        if query is not None and ep.QUERY_TAKEN in have:
            n = rank[query] = rank.get(query, -1) + 1
            seqs = taken_at.get(query, [])
            placeable.append((rec, msg, seqs[n] if n < len(seqs) else None))
    return _placed(base, sorted(placeable, key=lambda p: p[0].log_ns))


def _placed(
    base: list[tuple[Recorded, Message | None]],
    placeable: list[tuple[Recorded, Message | None, int | None]],
) -> list[tuple[Recorded, Message | None]]:
    """``base`` with each of ``placeable`` (record, message, after which joint state seq it
    was taken; None: not known, at its log time) put in: after that joint state and before
    the next, at its log time within that span (-1: before any joint state)."""
    times = [rec.log_ns for rec, _ in base]
    states = [i for i, (_, m) in enumerate(base) if isinstance(m, JointState)]
    at_seq = {m.seq: i for i, (_, m) in enumerate(base) if isinstance(m, JointState)}
    placed: list[tuple[int, int, Recorded, Message | None]] = []
    for order, (rec, msg, after_seq) in enumerate(placeable):
        pos = bisect.bisect_right(times, rec.log_ns)
        after = None if after_seq is None else at_seq.get(after_seq)
        if after is not None:  # within (that joint state, the next one]
            nxt = next((i for i in states if i > after), len(base))
            pos = min(max(pos, after + 1), nxt)
        elif after_seq is not None and after_seq < 0 and states:  # before any joint state
            pos = min(pos, states[0])
        placed.append((pos, order, rec, msg))
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
