"""The flight recorder: a fault at a known time gives one file with the seconds before and
after it, the file validates and replays, and memory stays under the cap in a flood."""

from __future__ import annotations

import itertools
import time
import tracemalloc
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from manus.node import Node, now_ns
from manus.session import ZenohSettings
from schemas.commands import EStop
from schemas.control import GoalResult
from schemas.endpoints import FLIGHT_TRIGGER
from schemas.flight import FlightTrigger
from schemas.state import ArmStatus, JointState
from services.recorder.errors import RecordingError
from services.recorder.flight import (
    ENTRY_OVERHEAD,
    Dump,
    FlightConfig,
    FlightCore,
    TriggerRules,
)
from services.recorder.flight_shell import FlightShell, write_dump
from services.recorder.reading import Recording
from services.recorder.replay import Replayer, schedule
from tests.conftest import eventually, matched_publisher

CYCLE_NS = 60_000_000
S = 1_000_000_000


def _joints(seq: int, t_ns: int) -> bytes:
    return JointState(
        stamp_ns=t_ns, seq=seq, position=[0.1 * seq % 1, 0.5, -0.5, 0.0, -1.0, 0.0],
        gripper=0.02, valid=True, mode="joint", encoder=[0] * 7, applied_velocity=[0.0] * 6,
        applied_gripper_velocity=0.0,
        applied_kind="joint", applied_seq=seq - 1,
    ).encode()  # fmt: skip


def _status(seq: int, t_ns: int, msg_class: str = "none", code: int = 0) -> bytes:
    text = {"error": "emergency stop", "warning": "motor blocked"}.get(msg_class, "")
    return ArmStatus(
        stamp_ns=t_ns, seq=seq, mode="joint", mode_code=4, msg_class=msg_class,
        msg_code=code, text=text,
    ).encode()  # fmt: skip


def _stream(
    core: FlightCore, seconds: float, fault_at_s: float, fault: str
) -> list[tuple[int, list[Dump]]]:
    """A cycle's joint state and status every 60 ms; from ``fault_at_s`` on the status
    reports the fault in every cycle (as the arm does)."""
    dumps = []
    for k in range(round(seconds * S / CYCLE_NS)):
        t = k * CYCLE_NS
        cls, code = (fault, 4 if fault == "error" else 3) if t >= fault_at_s * S else ("none", 0)
        for key, payload in (
            ("manus/state/status", _status(k, t + 20_000_000, cls, code)),
            ("manus/state/joints", _joints(k, t + 40_000_000)),
        ):
            out = core.on_sample(key, payload, t + (40_000_000 if "joints" in key else 20_000_000))
            dumps += [(t, list(out))] if out else []
    return dumps


def test_an_arm_error_gives_one_dump_with_the_seconds_before_and_after() -> None:
    core = FlightCore(FlightConfig(ring_s=5.0, after_s=2.0))
    dumps = [d for _, ds in _stream(core, 20.0, 10.0, "error") for d in ds]
    assert len(dumps) == 1  # the error repeats every cycle: one edge, one file
    dump = dumps[0]
    fault_ns = 10_040_000_000  # cycle 167 starts at 10.02 s, its status at +20 ms
    assert [t.kind for t in dump.triggers] == ["arm_error"]
    assert dump.triggers[0].t_ns == fault_ns
    times = [s.log_ns for s in dump.samples]
    assert times == sorted(times)
    assert fault_ns - 5 * S <= times[0] <= fault_ns - 5 * S + CYCLE_NS
    assert fault_ns + 2 * S - CYCLE_NS <= times[-1] < fault_ns + 2 * S
    keys = {s.key for s in dump.samples}
    assert keys == {"manus/state/status", "manus/state/joints"}
    assert dump.truncated == 0 and core.stats.triggers == 1


def test_warning_codes_goal_aborts_and_requests_trigger_only_when_chosen() -> None:
    quiet = FlightCore(FlightConfig(ring_s=2.0, after_s=0.5))
    assert _stream(quiet, 6.0, 3.0, "warning") == []  # no warning code chosen
    loud = FlightCore(FlightConfig(ring_s=2.0, after_s=0.5, rules=TriggerRules(warning_codes=(3,))))
    [(_, [dump])] = _stream(loud, 6.0, 3.0, "warning")
    assert dump.triggers[0].kind == "arm_warning"
    core = FlightCore(FlightConfig(ring_s=2.0, after_s=0.0))
    aborted = GoalResult(stamp_ns=1, seq=0, goal_id="g1", kind="trajectory", status="aborted",
                         cause="tolerance", reason="path tolerance")  # fmt: skip
    [d1] = core.on_sample("manus/controller/result", aborted.encode(), 1 * S)
    request = FlightTrigger(stamp_ns=2, seq=0, source="operator", reason="odd noise")
    [d2] = core.on_sample(f"manus/{FLIGHT_TRIGGER}", request.encode(), 2 * S)
    assert [d1.triggers[0].kind, d2.triggers[0].kind] == ["goal_aborted", "request"]
    assert core.on_sample("manus/estop", b"\xc1garbage", 3 * S) == []
    assert core.stats.bad_payloads == 1


def test_config_refuses_nonsense() -> None:
    with pytest.raises(RecordingError, match="ring 0 s"):
        FlightConfig(ring_s=0)
    with pytest.raises(RecordingError, match="memory cap"):
        FlightConfig(cap_bytes=10)


def test_memory_stays_under_the_cap_in_a_tenfold_flood() -> None:
    """Normal traffic (status, joints, bridge state at 16.7 Hz, 3 CAN frames a cycle)
    plus a flood ten times all of it on one key; 60 s into a 30 s ring, 1 MiB cap."""
    cap = 1024 * 1024
    core = FlightCore(FlightConfig(ring_s=30.0, after_s=1.0, cap_bytes=cap))
    status = _status(0, 0)
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    n = 0
    for k in range(1000):  # 60 s
        t = k * CYCLE_NS
        core.on_sample("manus/state/status", status + b"", t)  # a fresh object each
        core.on_sample("manus/state/joints", _joints(k, t), t + 1)
        for j in range(3):
            core.on_sample("manus/can/rx", bytes(30) + j.to_bytes(1, "little"), t + 2 + j)
        for j in range(60):  # the flood: ten times the 6 messages of a cycle
            core.on_sample("manus/flood", bytes(200) + n.to_bytes(4, "little"), t + 10 + j)
            n += 1
        assert core.stats.held_bytes <= cap
    used = tracemalloc.get_traced_memory()[0] - base
    tracemalloc.stop()
    assert core.stats.evicted_by_cap > 0
    assert used <= cap * 1.10, f"{used} B traced for {core.stats.held_bytes} B accounted"
    # the flood cost the flooding key its history, not the others theirs
    held = {k: len(q) for k, q in core._ring.items()}
    assert held["manus/state/status"] == 500  # the full 30 s
    assert held["manus/state/joints"] == 500
    assert ENTRY_OVERHEAD >= 100


# -- live ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_live_estop_gives_one_file_that_validates_and_replays(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    prefix = zenoh_settings.prefix
    config = FlightConfig(ring_s=1.5, after_s=1.0)
    with FlightShell(zenoh_settings, tmp_path, config) as shell, Node("arm", zenoh_settings) as n:
        joints = n.publisher(f"{prefix}/state/joints")
        estop = n.publisher(f"{prefix}/estop")
        time.sleep(0.3)
        fault_ns = 0
        for k in range(70):  # 4.2 s at 60 ms, the e-stop at 2.4 s
            joints.put(JointState.decode(_joints(k, now_ns())))
            if k == 40:
                fault_ns = now_ns()
                estop.put(EStop(stamp_ns=fault_ns, seq=0, engaged=True, source="test"))
            time.sleep(0.06)
        eventually(lambda: len(shell.files) == 1, 5.0, "one flight file")
        time.sleep(0.5)
        assert len(shell.files) == 1 and shell.dropped == 0
        path = shell.files[0]
    assert "emergency_stop" in path.name
    # validates: every CRC (chunks and data section) and the summary
    with path.open("rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
    assert records
    with path.open("rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert "emergency_stop" in meta["flight"]["triggers"]
    rec = Recording(path)
    times = [m.log_ns for m in rec.messages(["state/joints"])]
    # the configured seconds before (1.5 s) and after (1.0 s), within a cycle or two
    assert fault_ns - 1.5 * S <= times[0] <= fault_ns - 1.5 * S + 0.2 * S
    assert fault_ns + 0.8 * S <= times[-1] <= fault_ns + 1.0 * S
    # replays onto the bus: every recorded joint state arrives
    got: list[bytes] = []
    with Node("watch", zenoh_settings) as w:
        w.subscribe_raw(f"{prefix}/state/joints", lambda s, _t: got.append(s.payload.to_bytes()))
        items = schedule(rec, ["state/joints"], None)
        with Replayer(zenoh_settings, recording=rec) as replayer:
            replayer.play(items, rate=None)
        eventually(lambda: len(got) == len(times), 5.0, "replayed joint states")


def test_write_dump_writes_a_valid_file(tmp_path: Path) -> None:
    core = FlightCore(FlightConfig(ring_s=1.0, after_s=0.5))
    [(_, [dump])] = _stream(core, 3.0, 1.5, "error")
    path = tmp_path / "d.mcap"
    assert write_dump(dump, path, "manus") == len(dump.samples)
    assert Recording(path).info.messages == len(dump.samples)


def test_a_dump_is_written_in_slices_with_a_pause_between_them(tmp_path: Path) -> None:
    """Each message takes one tick of the fake clock (1/1024 s, exact in binary): a pause
    after every 5 (a slice of 5 ticks), and every message in the file, in order."""
    core = FlightCore(FlightConfig(ring_s=1.0, after_s=0.5))
    [(_, [dump])] = _stream(core, 3.0, 1.5, "error")
    ticks = itertools.count()
    pauses: list[int] = []
    clock = lambda: next(ticks) / 1024  # noqa: E731
    written = write_dump(
        dump, tmp_path / "d.mcap", "manus", slice_s=5 / 1024, clock=clock,
        pause=lambda: pauses.append(len(pauses)),
    )  # fmt: skip
    assert written == len(dump.samples) >= 50
    assert len(pauses) == len(dump.samples) // 5
    logged = [m.log_ns for m in Recording(tmp_path / "d.mcap").messages()]
    assert logged == [s.log_ns for s in dump.samples]


@pytest.mark.slow
def test_manus_record_trigger_asks_a_running_flight_recorder_to_write(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    from manus_stack.cli import main

    bus = ["--connect", *zenoh_settings.connect, "--prefix", zenoh_settings.prefix]
    with FlightShell(zenoh_settings, tmp_path, FlightConfig(ring_s=2.0, after_s=0.2)) as shell:
        assert main(["record", "--trigger", "the gripper slipped", *bus]) == 0
        eventually(lambda: len(shell.files) == 1, 5.0, "one flight file")
    path = shell.files[0]
    assert path.name.endswith("-request-manus-record-the-gripper-slipped.mcap")
    with path.open("rb") as f:
        meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert "the gripper slipped" in meta["flight"]["triggers"]


def test_config_splits_the_cap_between_the_queue_and_the_ring() -> None:
    config = FlightConfig(cap_bytes=1 << 20, queue_share=1 / 16)
    assert (config.queue_bytes, config.ring_cap_bytes) == (65536, (1 << 20) - 65536)
    with pytest.raises(RecordingError, match=r"queue share 0\.9"):
        FlightConfig(queue_share=0.9)
    core = FlightCore(config)
    for k in range(20_000):  # 4 MiB offered
        core.on_sample("manus/flood", bytes(100) + k.to_bytes(4, "little"), k)
    assert core.stats.peak_bytes <= config.ring_cap_bytes < config.cap_bytes


def test_the_live_queue_holds_its_share_of_the_cap_in_bytes(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    """The worker stalls (a slow disk): the queue takes samples until its byte budget is
    spent, then drops and counts; the ring and the queue together stay within the cap."""
    import threading

    cap = 256 * 1024
    release = threading.Event()
    with FlightShell(zenoh_settings, tmp_path, FlightConfig(cap_bytes=cap)) as shell:
        assert shell.queue_bytes == cap // 16
        assert shell.core.config.ring_cap_bytes == cap - cap // 16
        on_sample = shell.core.on_sample

        def stalled(key: str, payload: bytes, log_ns: int, publish_ns: int | None = None) -> Any:
            release.wait(10.0)
            return on_sample(key, payload, log_ns, publish_ns)

        shell.core.on_sample = stalled  # type: ignore[method-assign]
        try:
            with Node("pub", zenoh_settings) as node:
                # every sample to the shell, whose own queue is what drops them: once it
                # subscribed, and waiting for room on the way (under load 5, 180 drops
                # were not seen in 5 s: samples had been lost before the shell)
                pub = matched_publisher(node.session, f"{zenoh_settings.prefix}/flood", block=True)
                for k in range(200):  # 200 x (1000 + 200) B = 234 KiB offered, 16 KiB budget
                    pub.put(bytes(996) + k.to_bytes(4, "little"))
                eventually(lambda: shell.dropped >= 180, 5.0, "drops")
            assert shell.queue_peak <= shell.queue_bytes
            queued = [item for item in list(shell._queue.queue) if item is not None]
            assert sum(len(item[1]) + ENTRY_OVERHEAD for item in queued) <= shell.queue_bytes
        finally:
            release.set()
    assert shell.stats()["queue_peak_bytes"] == shell.queue_peak
