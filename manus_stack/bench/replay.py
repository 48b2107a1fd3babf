"""Replay and recorder speed: a long lock-step recording through the controller core as
fast as possible, and how fast the recorder writes.

The recording is made first (lock-step, the thesis square and circle alternately, each
planned from where the last left the arm; ``quick``: two paths, else eight). Figures:

- ``controller_core``: the recorded controller inputs (decoded beforehand) fed to a fresh
  :class:`ControllerCore` as its shell would: simulated seconds per CPU second
  (``x_real_time``; target >= 1000) and microseconds per input (default mode; the same
  for a recording made in the thesis mode: ``controller_core_thesis_mode``);
- ``check``: the whole regression check (read the MCAP, decode, run the core, compare
  every output byte for byte), also as ``x_real_time``;
- ``read``: reading and decoding every message of the recording (messages/s), and the
  controller's inputs alone (``controller_inputs_x_real_time``: the replay's own cost,
  without the core);
- ``writer``: :class:`RecordingWriter` writing every recorded payload again (as the live
  recorder does, stamp lookup included): messages/s and MB/s;
- ``recorder_zenoh``: the live recorder on a loopback router, fed by the replayer at full
  speed in the same process (both share the CPU): messages/s recorded and whether every
  one arrived.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from manus.session import client_settings, open_session, router_settings
from manus_stack.controlled import controller_input
from manus_stack.ports import free_port
from manus_stack.recordings import record_thesis_runs
from manus_stack.regression import check_controller
from schemas.base import Message
from services.controller.core import ControllerCore
from services.controller.wiring import WIRING as CONTROLLER
from services.recorder.reading import Recording, decode
from services.recorder.replay import Replayer, schedule
from services.recorder.shell import RecorderShell
from services.recorder.writer import RecordingWriter

TARGET_X_REAL_TIME = 1000.0


def _best(fn: Any, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        started = time.process_time()
        fn()
        best = min(best, time.process_time() - started)
    return max(best, 1e-9)


def _core_replay(inputs: list[tuple[str, Message]]) -> int:
    core = ControllerCore()
    outputs = 0
    for suffix, msg in inputs:
        outputs += len(controller_input(core, suffix, msg))
    return outputs


def _recorder_zenoh(path: Path, out: Path) -> dict[str, Any]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = open_session(router_settings(endpoint))
    try:
        settings = client_settings(endpoint, prefix="bench")
        items = schedule(Recording(path))
        with RecorderShell(settings, out) as recorder, Replayer(settings) as replayer:
            replayer.wait_for_subscribers(sorted({i.rec.suffix for i in items}))
            started = time.perf_counter()
            replayer.play(items, rate=None)
            deadline = time.monotonic() + 30.0
            while recorder.samples_recorded < len(items) and time.monotonic() < deadline:
                time.sleep(0.005)
            elapsed = time.perf_counter() - started
            recorded = recorder.samples_recorded
        size = sum(len(i.rec.payload) for i in items)
        return {
            "sent": len(items),
            "recorded": recorded,
            "all_recorded": recorded == len(items),
            "messages_per_s": round(recorded / elapsed),
            "mb_per_s": round(size / elapsed / 1e6, 2),
        }
    finally:
        router.close()


def run(quick: bool = False) -> dict[str, Any]:
    """Figures of replay through the controller core and of the recorder."""
    shapes = ["square", "circle"] * (1 if quick else 4)
    repeats = 2 if quick else 5
    with tempfile.TemporaryDirectory(prefix="manus-bench-replay-") as tmp:
        path = Path(tmp) / "long.mcap"
        made = time.process_time()
        run_ = record_thesis_runs(shapes, path)
        lockstep_cpu = time.process_time() - made
        rec = Recording(path)
        span = rec.info.duration_s
        inputs = [(r.suffix, decode(r)) for r in rec.messages(CONTROLLER.input_suffixes)]
        everything = list(rec.messages())
        nbytes = sum(len(r.payload) for r in everything)

        core_s = _best(lambda: _core_replay(inputs), repeats)
        check_result = check_controller(path)
        check_s = _best(lambda: check_controller(path), max(1, repeats // 2))
        read_s = _best(lambda: [decode(r) for r in rec.messages()], max(1, repeats // 2))
        io_s = _best(
            lambda: [decode(r) for r in rec.messages(CONTROLLER.input_suffixes)],
            max(1, repeats // 2),
        )

        def rewrite() -> None:
            with RecordingWriter(Path(tmp) / "rewrite.mcap") as writer:
                for r in everything:
                    writer.write_payload(r.key, r.payload, r.log_ns, r.publish_ns)

        write_s = _best(rewrite, max(1, repeats // 2))
        thesis_path = Path(tmp) / "thesis_mode.mcap"
        record_thesis_runs(shapes, thesis_path, mode="thesis")
        thesis = Recording(thesis_path)
        thesis_inputs = [(r.suffix, decode(r)) for r in thesis.messages(CONTROLLER.input_suffixes)]
        thesis_s = _best(lambda: _core_replay(thesis_inputs), repeats)
        live = _recorder_zenoh(path, Path(tmp) / "live.mcap")
        return {
            "recording": {
                "paths": len(shapes),
                "simulated_s": round(span, 1),
                "messages": len(everything),
                "controller_inputs": len(inputs),
                "bytes": nbytes,
                "file_bytes": path.stat().st_size,
                "lockstep_cpu_s": round(lockstep_cpu, 2),
                "last_status": run_.status,
            },
            "controller_core": {
                "cpu_s": round(core_s, 4),
                "x_real_time": round(span / core_s),
                "us_per_input": round(core_s / len(inputs) * 1e6, 1),
                "target_x_real_time": TARGET_X_REAL_TIME,
                "met": span / core_s >= TARGET_X_REAL_TIME,
            },
            "controller_core_thesis_mode": {
                "simulated_s": round(thesis.info.duration_s, 1),
                "cpu_s": round(thesis_s, 4),
                "x_real_time": round(thesis.info.duration_s / thesis_s),
                "us_per_input": round(thesis_s / len(thesis_inputs) * 1e6, 1),
            },
            "check": {
                "ok": check_result.ok,
                "compared": check_result.compared,
                "cpu_s": round(check_s, 4),
                "x_real_time": round(span / check_s),
            },
            "read": {
                "messages_per_s": round(len(everything) / read_s),
                "controller_inputs_x_real_time": round(span / io_s),
            },
            "writer": {
                "messages_per_s": round(len(everything) / write_s),
                "mb_per_s": round(nbytes / write_s / 1e6, 2),
            },
            "recorder_zenoh": live,
        }
