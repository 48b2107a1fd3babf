"""The flight recorder's memory under a flood: ``manus bench flight``.

``core``: :class:`services.recorder.flight.FlightCore` (30 s ring) fed the thesis square
recording's traffic ten times over (each recorded sample ten times, fresh bytes each), for
``seconds`` of log time, with a memory cap well below what 30 s of that would take: the
most bytes it accounted, the memory ``tracemalloc`` saw it hold, the cap, samples evicted
early, and the cost per sample.

``live``: ``manus record --ring 30`` in its own process on a loopback router while a
publisher here sends that tenfold traffic in real time: the recorder process's resident
memory before, at most (sampled every 0.25 s) and after, split as the kernel counts it
(``RssAnon``: its own heap, where the ring lives; ``RssFile``: mapped code; ``RssShmem``:
shared memory, e.g. Zenoh's pool of another process), the bytes it held at most, the
samples its queue dropped and the most bytes its queue held.

``dump``: a full 30 s ring of the stack's own traffic (the recording's, looped) written
as a flight file in one go and in slices (:func:`services.recorder.flight_shell.write_dump`):
the time each takes and its longest stretch without a pause (CPU taken from the rest of the
stack in one burst).
"""

from __future__ import annotations

import gc
import json
import math
import signal
import socket
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

import psutil
import zenoh

from manus.session import client_settings, open_session, router_settings
from services.recorder.flight import Dump, FlightConfig, FlightCore, Sample, Trigger
from services.recorder.flight_shell import PAUSE_S, SLICE_S, write_dump
from services.recorder.reading import Recording

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "thesis_square.mcap"
MIB = 1024 * 1024


def _rss_split(pid: int) -> dict[str, float]:
    """``RssAnon``, ``RssFile`` and ``RssShmem`` of a process [MiB] (Linux)."""
    out = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            name, _, value = line.partition(":")
            if name in ("RssAnon", "RssFile", "RssShmem"):
                out[name] = round(int(value.split()[0]) / 1024, 1)
    return out


def _traffic() -> tuple[list[tuple[str, bytes, int]], int]:
    """The recording's samples (key suffix, payload, offset [ns]) and its span [ns]."""
    rec = Recording(DATA)
    first = rec.info.start_ns
    items = [(m.suffix, m.payload, m.log_ns - first) for m in rec.messages()]
    return items, rec.info.end_ns - first + 60_000_000


def _core(seconds: float, cap: int) -> dict[str, Any]:
    items, span = _traffic()
    keys = {suffix: f"manus/{suffix}" for suffix, _, _ in items}  # one str per key, as live
    timing = FlightCore(FlightConfig(ring_s=30.0, after_s=1.0, cap_bytes=cap))
    t0 = time.perf_counter()
    for suffix, payload, t in items:  # the cost per sample, without tracemalloc's own
        for copy in range(10):
            timing.on_sample(keys[suffix], payload + bytes([copy]), t)
    us_per_sample = 1e6 * (time.perf_counter() - t0) / (10 * len(items))
    gc.collect()
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    core = FlightCore(FlightConfig(ring_s=30.0, after_s=1.0, cap_bytes=cap))
    n = 0
    peak_used = 0
    offset = 0
    while offset < seconds * 1e9:
        for suffix, payload, t in items:
            for copy in range(10):
                core.on_sample(keys[suffix], payload + bytes([copy]), offset + t)
                n += 1
        offset += span
        peak_used = max(peak_used, tracemalloc.get_traced_memory()[0] - base)
    used = tracemalloc.get_traced_memory()[0] - base
    tracemalloc.stop()
    return {
        "samples": n,
        "samples_per_s_of_log_time": round(n / (offset / 1e9)),
        "cap_mib": round(cap / MIB, 2),
        "held_mib": round(core.stats.held_bytes / MIB, 2),
        "peak_accounted_mib": round(core.stats.peak_bytes / MIB, 2),
        "traced_mib": round(used / MIB, 2),
        "peak_traced_mib": round(peak_used / MIB, 2),
        "evicted_by_cap": core.stats.evicted_by_cap,
        "us_per_sample": round(us_per_sample, 2),
    }


def _flood(
    session: zenoh.Session,
    items: list[tuple[str, bytes, int]],
    span: int,
    seconds: float,
    proc: psutil.Process,
) -> tuple[int, float, int, list[float]]:
    """Publish ``items`` ten times over at their recorded pace, looping, for ``seconds``;
    sample ``proc``'s resident memory meanwhile: (sent, elapsed [s], most RSS [B], RSS
    every 5 s [MiB])."""
    pubs: dict[str, zenoh.Publisher] = {}
    sent = 0
    t0 = time.monotonic()
    offset = 0.0
    rss_max = proc.memory_info().rss
    next_probe = next_series = t0
    series: list[float] = []
    while time.monotonic() - t0 < seconds:
        for suffix, payload, t in items:
            delay = t0 + offset + t / 1e9 - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            pub = pubs.get(suffix)
            if pub is None:
                pub = pubs[suffix] = session.declare_publisher(f"benchflight/{suffix}")
            for copy in range(10):
                pub.put(payload + bytes([copy]))
                sent += 1
            if time.monotonic() >= next_probe:
                rss = proc.memory_info().rss
                rss_max = max(rss_max, rss)
                next_probe += 0.25
                if time.monotonic() >= next_series:
                    series.append(round(rss / MIB, 1))
                    next_series += 5.0
            if time.monotonic() - t0 >= seconds:
                break
        offset += span / 1e9
    elapsed = time.monotonic() - t0
    for pub in pubs.values():
        pub.undeclare()
    return sent, elapsed, rss_max, series


def _live(seconds: float, cap: int) -> dict[str, Any]:
    items, span = _traffic()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{s.getsockname()[1]}"
    router = open_session(router_settings(endpoint))
    try:
        settings = client_settings(endpoint, prefix="benchflight")
        with tempfile.TemporaryDirectory() as tmp:
            argv = [sys.executable, "-m", "manus_stack.cli", "record", "--ring", "30",
                    "--ring-mib", f"{cap / MIB:g}", "--out-dir", tmp, "--connect", endpoint,
                    "--prefix", "benchflight"]  # fmt: skip
            child = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)
            try:
                assert child.stderr is not None
                child.stderr.readline()  # "flight recorder: ..." once it listens
                proc = psutil.Process(child.pid)
                time.sleep(1.0)
                rss0 = proc.memory_info().rss
                split0 = _rss_split(child.pid)
                pub_session = open_session(settings)
                flood = _flood(pub_session, items, span, seconds, proc)
                sent, elapsed, rss_max, series = flood
                time.sleep(0.5)
                rss1 = proc.memory_info().rss
                split1 = _rss_split(child.pid)
                rss_max = max(rss_max, rss1)
                pub_session.close()
            finally:
                child.send_signal(signal.SIGINT)
                _, err = child.communicate(timeout=30)
            stats = json.loads(err.split("stats: ", 1)[1].splitlines()[0])
    finally:
        router.close()
    return {
        "seconds": round(elapsed, 1),
        "sent": sent,
        "sent_per_s": round(sent / elapsed),
        "received": stats["samples"],
        "dropped_by_queue": stats["dropped"],
        "cap_mib": round(cap / MIB, 2),
        "peak_accounted_mib": round(stats["peak_bytes"] / MIB, 2),
        "evicted_by_cap": stats["evicted_by_cap"],
        "rss_before_mib": round(rss0 / MIB, 1),
        "rss_max_mib": round(rss_max / MIB, 1),
        "rss_after_mib": round(rss1 / MIB, 1),
        "rss_every_5s_mib": series,
        "rss_split_before_mib": split0,
        "rss_split_after_mib": split1,
        "queue_mib": round(stats["queue_bytes"] / MIB, 2),
        "queue_peak_mib": round(stats["queue_peak_bytes"] / MIB, 2),
        "ring_added_mib": round(split1["RssAnon"] - split0["RssAnon"], 1),
    }


def _dump(ring_s: float = 30.0) -> dict[str, Any]:
    """A full ring of the recording's traffic (once, not tenfold) written in one go and in
    slices: messages, write time [ms], longest stretch without a pause [ms], pauses."""
    items, span = _traffic()
    samples: list[Sample] = []
    offset = 0
    while offset < ring_s * 1e9:
        for suffix, payload, t in items:
            samples.append(Sample(len(samples), f"manus/{suffix}", payload, offset + t, None))
        offset += span
    last_ns = samples[-1].log_ns
    dump = Dump([Trigger(last_ns, "request", "bench")], samples[0].log_ns, last_ns, samples)
    out: dict[str, Any] = {"messages": len(samples)}
    with tempfile.TemporaryDirectory() as tmp:
        for name, slice_s in (("one_go", math.inf), ("sliced", SLICE_S)):
            out[name] = _timed_write(dump, Path(tmp) / f"{name}.mcap", slice_s)
    return out


def _timed_write(dump: Dump, path: Path, slice_s: float) -> dict[str, Any]:
    """Write ``dump`` in slices of ``slice_s`` [s]: its time, longest stretch, pauses."""
    stretches: list[float] = []
    mark = time.perf_counter()

    def pause() -> None:
        nonlocal mark
        stretches.append(time.perf_counter() - mark)
        time.sleep(PAUSE_S)
        mark = time.perf_counter()

    start = time.perf_counter()
    write_dump(dump, path, "manus", slice_s=slice_s, pause=pause)
    stretches.append(time.perf_counter() - mark)  # the last, closing the file
    return {
        "write_ms": round((time.perf_counter() - start) * 1e3, 1),
        "longest_stretch_ms": round(max(stretches) * 1e3, 1),
        "pauses": len(stretches) - 1,
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Core, live and dump figures (a 4 MiB cap: a 30 s ring of the tenfold traffic needs
    ~25)."""
    cap = 4 * MIB
    return {
        "core": _core(40.0 if quick else 120.0, cap),
        "live": _live(10.0 if quick else 90.0, cap),
        "dump": _dump(),
    }
