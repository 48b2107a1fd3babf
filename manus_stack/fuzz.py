"""Seeded fuzzing of every bus endpoint and every CAN id the bridge reads.

**Payloads** (:func:`payloads`): for a message type, a seeded mix of random bytes,
valid MessagePack of the wrong shape (scalars, lists, maps of random keys), a valid
message with a field dropped, retyped, set to NaN / infinity / 1e308 or grown into a huge
array, extra fields, deep nesting (100 000 nested arrays), and a valid message of
another type. The endpoints come from :func:`schemas.keys.channel_types` (every published
key and every queryable's request), so a new key is fuzzed without editing this module.

**Core level** (:func:`fuzz_cores`): every payload is decoded as its endpoint's type
(which must either give a message or raise :class:`~manus.errors.SchemaError`, the one
error the live shells count), and what decodes is handed to the cores that take that
endpoint in the lock-step stack (bridge, controller, planner) while the arm runs, or to
the sequencer core's request handlers (a task is validated as the sequencer does, the
planner in process). Then
the CAN side (:func:`fuzz_can`): random frames with the ids the bridge reads (0x350,
0x360, 0x37F, the reply ids of other nodes) and random ids, random data and lengths,
remote or not, injected into the bridge's input among the arm's frames (the arm does not
see them). Afterwards the thesis square must succeed on the same lock-step stack. Any
exception other than a counted refusal is a finding, reported with its seed and input.
"""

from __future__ import annotations

import dataclasses
import math
import random
import types
import typing
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgpack

from manus.errors import ManusError, SchemaError
from manus.protocol import REPLY_IDS, Frame, FrameId
from manus_stack.controlled import ControlledArm, controller_input
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmCommand, EStop
from schemas.control import TrajectoryGoal
from schemas.keys import channel_types
from schemas.planning import PlanRequest
from schemas.sequencing import Task, TaskControl
from schemas.state import BridgeState, JointState
from schemas.tagged import TaggedUnion
from services.planner.core import PlannerCore
from services.sequencer.core import SequencerCore
from services.sequencer.validate import Validator
from services.simulator.config import SimConfig

PATHS = Path(__file__).resolve().parents[1] / "paths"
KINDS = (
    "random_bytes",
    "wrong_shape",
    "missing_field",
    "wrong_type",
    "non_finite",
    "huge_array",
    "extra_field",
    "deep_nesting",
    "other_type",
    "valid",
)
"""The kinds of payload :func:`payloads` makes, in turn."""
BRIDGE_IDS = (FrameId.STATUS, FrameId.POSITION, FrameId.SYNC, *sorted(REPLY_IDS))
"""CAN ids the bridge reads: the arm's three and other nodes' replies."""


def example(cls: type[Message], rng: random.Random) -> Message:
    """A valid instance of ``cls`` with every field set (nested types recursively)."""
    hints = typing.get_type_hints(cls)
    kwargs = {
        f.name: _value(hints[f.name], f.metadata, rng)
        for f in dataclasses.fields(cls)  # type: ignore[arg-type]
    }
    return cls(**kwargs)


def _value(tp: Any, meta: Any, rng: random.Random) -> Any:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return _value(next(a for a in args if a is not type(None)), meta, rng)
    if origin is list:
        n = meta.get("length") or rng.randint(0, 3)
        return [_value(args[0], meta, rng) for _ in range(n)]
    if isinstance(tp, type) and issubclass(tp, Message):
        union = meta.get("union") if meta else None
        if isinstance(union, TaggedUnion):  # one of its members, in turn at random
            tp = union.members[rng.choice(union.kinds())]
        return example(tp, rng)
    make = _SCALAR.get(tp)
    if make is None:
        raise TypeError(f"no example value for {tp!r}")
    return make(meta, rng)


def _number(meta: Any, default: float) -> tuple[float, float]:
    lo, hi = meta.get("minimum"), meta.get("maximum")
    a = float(lo) if lo is not None else -default
    return a, float(hi) if hi is not None else a + 2 * default


_SCALAR: dict[Any, Callable[[Any, random.Random], Any]] = {
    bool: lambda meta, rng: rng.random() < 0.5,
    int: lambda meta, rng: rng.randint(*(int(v) for v in _number(meta, 5.0))),
    float: lambda meta, rng: rng.uniform(*_number(meta, 1.0)),
    str: lambda meta, rng: rng.choice(meta.get("choices") or ["", "x", "fuzz"]),
    bytes: lambda meta, rng: rng.randbytes(rng.randint(0, 8)),
}
"""A valid random value of each scalar field type, within the field's limits."""

_WRONG: tuple[Callable[[random.Random, int], Any], ...] = (
    lambda rng, depth: rng.randint(-(2**63), 2**63 - 1),
    lambda rng, depth: rng.choice([math.nan, math.inf, -math.inf, 1e308, -0.0, rng.random()]),
    lambda rng, depth: rng.choice(["", "x" * rng.randint(0, 300), "\u00e9\u4e2d", "running"]),
    lambda rng, depth: rng.choice([None, True, False]),
    lambda rng, depth: rng.randbytes(rng.randint(0, 40)),
    lambda rng, depth: [_random_value(rng, depth + 1) for _ in range(rng.randint(0, 5))],
    lambda rng, depth: {
        rng.choice(["seq", "stamp_ns", "a", "", "id"]): _random_value(rng, depth + 1)
    },
    lambda rng, depth: {"steps": [_random_value(rng, depth + 1)]},
)
"""Makers of MessagePack values of any shape; the last three nest (not below depth 3)."""


def _random_value(rng: random.Random, depth: int = 0) -> Any:
    return _WRONG[rng.randrange(len(_WRONG) if depth < 3 else 5)](rng, depth)


def _pack(obj: Any) -> bytes:
    return bytes(msgpack.packb(obj, use_bin_type=True))


def payload(cls: type[Message], kind: str, rng: random.Random) -> bytes:
    """One fuzz payload of ``kind`` (:data:`KINDS`) for an endpoint of type ``cls``."""
    if kind == "random_bytes":
        return rng.randbytes(rng.randint(0, 64))
    if kind == "wrong_shape":
        return _pack(_random_value(rng))
    if kind == "deep_nesting":
        depth = 100_000
        return b"\x91" * depth + b"\xc0"  # [[[...[nil]...]]]
    if kind == "other_type":
        others = [t for t in set(channel_types().values()) if t is not cls]
        other = rng.choice(sorted(others, key=lambda t: t.TYPE_NAME))
        return example(other, rng).encode()
    d = example(cls, rng).to_dict()
    names = sorted(d)
    name = rng.choice(names) if names else ""
    if kind == "missing_field" and names:
        del d[name]
    elif kind == "wrong_type" and names:
        d[name] = _random_value(rng)
    elif kind == "non_finite":
        for k in names:
            if isinstance(d[k], float):
                d[k] = rng.choice([math.nan, math.inf, -math.inf, 1e308])
            elif isinstance(d[k], list) and d[k] and isinstance(d[k][0], float):
                d[k] = [rng.choice([math.nan, math.inf, 1e308]) for _ in d[k]]
    elif kind == "huge_array" and names:
        d[name] = [rng.random() for _ in range(100_000)]
    elif kind == "extra_field":
        d["fuzz_extra"] = _random_value(rng)
    return _pack(d)


def payloads(cls: type[Message], count: int, rng: random.Random) -> Iterator[tuple[str, bytes]]:
    """``count`` payloads for an endpoint of type ``cls``, cycling through :data:`KINDS`."""
    for i in range(count):
        kind = KINDS[i % len(KINDS)]
        yield kind, payload(cls, kind, rng)


@dataclass
class FuzzReport:
    """What a fuzz run tried and found.

    Attributes:
        seed: the random seed.
        inputs: payloads tried per endpoint (channel name of :func:`channel_types`).
        decoded: of those, how many decoded to a message (valid or not for the core).
        refused: decoded messages a core refused with its own error (counted, no crash).
        validated: decoded tasks validated as the sequencer does (planner in process).
        can_frames: random CAN frames given to the bridge.
        crashes: unexpected exceptions, each naming the endpoint, kind and error.
        task_after: status of the thesis square run afterwards.
        bridge_counts: the bridge's health counters at the end.
    """

    seed: int
    inputs: dict[str, int] = field(default_factory=dict)
    decoded: dict[str, int] = field(default_factory=dict)
    refused: int = 0
    validated: int = 0
    can_frames: int = 0
    crashes: list[str] = field(default_factory=list)
    task_after: str = ""
    bridge_counts: dict[str, Any] = field(default_factory=dict)


def _validate(task: Task, seq: SequencerCore) -> None:
    """The sequencer's validation of a submitted task, the planner in process."""
    validator = Validator(task, seq.start_configuration(), seq.config.arm)
    planner = PlannerCore()
    while (request := validator.next_request()) is not None:
        validator.on_reply(planner.plan(request))


def _deliver(
    arm: ControlledArm, seq: SequencerCore, channel: str, msg: Message, report: FuzzReport
) -> None:
    """Hand a decoded message to the lock-step cores that take ``channel`` (and the
    sequencer core's request handlers)."""
    ls = arm.ls
    suffix, _, part = channel.partition("#")
    endpoint = ep.TABLE.get(suffix)
    try:
        if part == "request" and endpoint is ep.PLAN and isinstance(msg, PlanRequest):
            PlannerCore().plan(msg)
        elif part == "request" and isinstance(msg, Task):
            refused = seq.refuse(msg)
            assert refused is None, refused  # the sequencer was primed to accept tasks
            _validate(msg, seq)
            report.validated += 1
        elif part == "request" and isinstance(msg, TaskControl):
            seq.control(msg, ls.t_ns)
        elif part == "request" and endpoint is ep.BRIDGE_COMMAND:
            ls.publish(ep.BRIDGE_COMMAND.trace("request"), msg)
            ls.arm_command(msg)  # type: ignore[arg-type]
        elif part == "request" and endpoint is not None and endpoint.kind is ep.Kind.QUERYABLE:
            ls.publish(endpoint.trace("request"), msg)
        elif endpoint in (ep.JOINT_VELOCITY, ep.ESTOP):
            ls.publish(suffix, msg)
        else:
            controller_input(arm.core, suffix, msg, ls.t_ns)
    except ManusError:
        report.refused += 1


def fuzz_cores(seed: int, per_endpoint: int) -> tuple[FuzzReport, ControlledArm]:
    """Every endpoint's payloads through decode and the lock-step cores (module docstring)."""
    rng = random.Random(seed)
    report = FuzzReport(seed)
    arm = ControlledArm(SimConfig(start_pose="unfolded", seed=seed))
    arm.start()
    seq = SequencerCore()
    for service in seq.config.required_services:  # a sequencer that would accept tasks
        seq.on_liveliness(service, True, arm.ls.t_ns)
    bridge_state = arm.ls.published(ep.BRIDGE_STATE)[-1]
    joint_state = arm.ls.published(ep.JOINTS)[-1]
    assert isinstance(bridge_state, BridgeState) and isinstance(joint_state, JointState)
    seq.on_bridge_state(bridge_state, arm.ls.t_ns)
    seq.on_joint_state(joint_state, arm.ls.t_ns)
    for channel, cls in sorted(channel_types().items()):
        for kind, data in payloads(cls, per_endpoint, rng):
            report.inputs[channel] = report.inputs.get(channel, 0) + 1
            try:
                msg = cls.decode(data)
            except SchemaError:
                continue
            except Exception as exc:
                report.crashes.append(f"{channel} {kind}: decode raised {exc!r:.300}")
                continue
            report.decoded[channel] = report.decoded.get(channel, 0) + 1
            try:
                _deliver(arm, seq, channel, msg, report)
                arm.ls.run_for(rng.uniform(0.0, 0.03))
            except Exception as exc:
                report.crashes.append(f"{channel} {kind}: {type(exc).__name__}: {exc!s:.300}")
    return report, arm


def random_frame(rng: random.Random, t_ns: int) -> Frame:
    """A frame with an id the bridge reads (or any id, one in five), random length and data."""
    fid = rng.choice(BRIDGE_IDS) if rng.random() < 0.8 else rng.randrange(0x800)
    dlc = rng.randint(0, 8)
    remote = rng.random() < 0.15
    data = b"" if remote else rng.randbytes(dlc)
    return Frame(fid, data, remote, t_ns, dlc)


def fuzz_can(arm: ControlledArm, seed: int, frames: int, report: FuzzReport) -> None:
    """Random frames into the bridge's input, a few per cycle (module docstring)."""
    rng = random.Random(seed + 1)
    ls = arm.ls
    for _ in range(frames):
        ls.run_for(rng.uniform(0.0, 0.02))
        try:
            ls.bridge_input(random_frame(rng, ls.t_ns))
        except Exception as exc:
            report.crashes.append(f"CAN frame: {type(exc).__name__}: {exc!s:.300}")
        report.can_frames += 1


def task_after(arm: ControlledArm) -> str:
    """The documented recovery (e-stop released, ``clear``), a fold out (valid fuzzed goals
    may have left the arm anywhere), then the thesis square."""
    ls = arm.ls
    ls.publish(ep.ESTOP, EStop(stamp_ns=ls.t_ns, seq=0, engaged=False, source="fuzz"))
    ls.run_for(2.0)
    if ls.bridge.phase != "running":
        ls.arm_command(ArmCommand(action="clear", source="fuzz"))
    ls.run_until_phase("running", timeout_s=10.0)
    ls.arm_command(ArmCommand(action="fold_out", source="fuzz"))
    ls.run_for(0.5)
    ls.run_until_phase("running", timeout_s=60.0)
    ls.run_for(0.5)
    try:
        traj = arm.plan(PATHS / "thesis_square.txt")
    except RuntimeError as exc:
        return f"not planned: {exc}"
    ack = arm.submit(TrajectoryGoal(goal_id="after-fuzz", trajectory=traj))
    if not ack.accepted:
        return f"refused: {ack.reason}"
    return arm.run_until_result("after-fuzz").status


def run_fuzz(seed: int = 0, per_endpoint: int = 20, frames: int = 2000) -> FuzzReport:
    """Core-level fuzz of every endpoint, then of the CAN input, then a task."""
    report, arm = fuzz_cores(seed, per_endpoint)
    fuzz_can(arm, seed, frames, report)
    report.task_after = task_after(arm)
    report.bridge_counts = dataclasses.asdict(arm.ls.bridge.health)
    return report
