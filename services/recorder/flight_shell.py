"""The flight recorder's live shell (``manus record --ring S``) and its files.

Zenoh callbacks stamp each sample and put it in a bounded queue: at most ``queue_size``
samples and :data:`QUEUE_SHARE` of the memory cap in bytes (payload plus
:data:`~services.recorder.flight.ENTRY_OVERHEAD` each, as the ring counts them); the ring
gets the rest of the cap, so the queue and the ring together stay within it. When the
queue is full a sample is dropped and counted, so neither a flood nor a slow disk grows
memory past the cap. One worker feeds :class:`~services.recorder.flight.FlightCore`, ticks it
when the bus is quiet, and writes each completed dump with :func:`write_dump` into
``out_dir`` as ``flight-<UTC time>-<trigger>.mcap``: an ordinary recording (CRCs,
summary) that ``manus replay``, ``manus export`` and ``manus plot`` read, with a
``flight`` metadata record (the triggers, the window), in slices of :data:`SLICE_S` of CPU
with a pause of :data:`PAUSE_S` between them (see :func:`write_dump`). Liveliness changes
are recorded and fed to the core as the recorder does (``<prefix>/liveliness``), so a
vanished service is a trigger. It listens only. It runs as the recorder (tokens
``alive/recorder`` and ``where/recorder/<host>/<pid>``, the recorder's identity in the
deployed access control), so a recorder and a flight recorder show as two recorder
processes.

Its own session runs without Zenoh's shared-memory transport
(``transport/shared_memory/enabled: false``): with it on (Zenoh 1.x's default), the first
message of 3 KiB or more from a process on the same host (a plan reply, a goal request)
maps that process's 16 MiB shared-memory pool into this one, and the resident size then
counts it (16 MiB that are not the ring's, measured: docs/flight.md, Where the memory goes). The
recorder copies every payload anyway, so shared memory gains it nothing.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import zenoh

from manus.node import Node, now_ns
from manus.session import ZenohSettings
from schemas.endpoints import Service
from schemas.liveliness import LivelinessChange
from services.recorder.flight import ENTRY_OVERHEAD, Dump, FlightConfig, FlightCore
from services.recorder.writer import RecordingWriter

log = logging.getLogger("manus.recorder.flight")

DEFAULT_QUEUE = 100_000
"""Samples waiting for the worker before new ones are dropped."""
QUEUE_SHARE = 1 / 16
"""Share of the memory cap the queue may hold (bytes); the ring gets the rest."""
NO_SHARED_MEMORY = {"transport/shared_memory/enabled": False}
"""Zenoh settings of the flight recorder's own session (see the module docstring)."""
NAME = Service.RECORDER
"""Liveliness name of the flight recorder: the recorder's."""

SLICE_S = 0.005
"""Longest stretch of CPU a dump is written in at once [s] (see :func:`write_dump`)."""
PAUSE_S = 0.005
"""Pause between two slices of a dump [s]."""

_Item = tuple[str, bytes, int, int | None]


def dump_name(dump: Dump) -> str:
    """``flight-<UTC time of the first trigger, ms>-<its slug>.mcap``."""
    first = dump.triggers[0]
    t = first.t_ns
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime(t // 1_000_000_000))
    return f"flight-{stamp}.{(t // 1_000_000) % 1000:03d}-{first.slug}.mcap"


def write_dump(
    dump: Dump,
    path: Path,
    prefix: str,
    *,
    slice_s: float = SLICE_S,
    pause: Callable[[], None] = lambda: time.sleep(PAUSE_S),
    clock: Callable[[], float] = time.perf_counter,
) -> int:
    """Write ``dump`` as a recording at ``path``; returns the messages written.

    A full ring (about 6500 messages of the stack's traffic) written in one go is a burst
    of 120-210 ms on one of the machine's two cores; under load it once delayed a joint
    state another process received by 77 ms (docs/deployment.md, Chaos soak). So the
    messages are written in slices, with a pause (the CPU and the GIL go to others) after
    each.

    Args:
        dump: what to write.
        path: the file.
        prefix: key prefix of the arm (the recording's channels).
        slice_s: the longest stretch written without a pause, by ``clock`` [s].
        pause: called between two slices (default: sleep :data:`PAUSE_S`).
        clock: a monotonic clock [s].
    """
    with RecordingWriter(path, prefix=prefix, source="manus record --ring") as writer:
        writer.add_metadata(
            "flight",
            {
                "triggers": json.dumps(
                    [{"t_ns": t.t_ns, "kind": t.kind, "detail": t.detail} for t in dump.triggers]
                ),
                "start_ns": str(dump.start_ns),
                "end_ns": str(dump.end_ns),
                "truncated": str(dump.truncated),
            },
        )
        start = clock()
        for s in dump.samples:
            writer.write_payload(s.key, s.payload, s.log_ns, s.publish_ns)
            if clock() - start >= slice_s:
                pause()
                start = clock()
        return writer.stats.messages


class FlightShell:
    """Keeps the last seconds of one arm's bus and writes them when a trigger fires.

    Args:
        settings: how to reach the bus; its prefix selects the arm.
        out_dir: where the files go (created).
        config: ring, after-window, memory cap (the queue's share and the ring's
            together), triggers (its prefix is replaced by the settings').
        session: an open session to share (not closed by :meth:`close`).
        queue_size: samples buffered before new ones are dropped.

    Attributes:
        files: the files written so far.
        dropped: samples dropped because the queue was full (in samples or bytes).
        queue_bytes: the queue's byte budget (its share of the cap).
        write_errors: dumps that could not be written.
    """

    def __init__(
        self,
        settings: ZenohSettings,
        out_dir: str | Path,
        config: FlightConfig | None = None,
        *,
        session: zenoh.Session | None = None,
        queue_size: int = DEFAULT_QUEUE,
    ) -> None:
        base = config or FlightConfig()
        self.core = FlightCore(
            replace(base, prefix=settings.prefix, queue_share=base.queue_share or QUEUE_SHARE)
        )
        self.queue_bytes = self.core.config.queue_bytes
        self._queued = 0  # bytes in the queue (payload + overhead)
        self.queue_peak = 0
        """The most bytes the queue held."""
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.prefix = settings.prefix
        self.files: list[Path] = []
        self.dropped = 0
        self.write_errors = 0
        self._lock = threading.Lock()
        self._keys: dict[str, str] = {}  # one str object per key: the ring holds many
        self._queue: queue.Queue[_Item | None] = queue.Queue(maxsize=queue_size)
        self._seq = 0
        self._closing = False
        self._thread = threading.Thread(target=self._work, name="flight-recorder", daemon=True)
        self._thread.start()
        if session is None:
            settings = replace(settings, extra={**settings.extra, **NO_SHARED_MEMORY})
        self.node = Node(NAME, settings, session=session, liveliness=False)
        self._liveliness_key = self.node.keys.liveliness
        self.node.subscribe_raw(self.node.keys.all, self._on_sample)
        self.node.watch_tokens(self.node.keys.all, self._on_token)
        self.node.announce()

    def _offer(self, item: _Item) -> None:
        cost = len(item[1]) + ENTRY_OVERHEAD
        with self._lock:
            if self._queued + cost > self.queue_bytes:
                self.dropped += 1
                return
            self._queued += cost
            self.queue_peak = max(self.queue_peak, self._queued)
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            with self._lock:
                self._queued -= cost
                self.dropped += 1

    def _on_sample(self, sample: zenoh.Sample, rx_ns: int) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        key = str(sample.key_expr)
        if key == self._liveliness_key:  # the recording channel: nobody publishes there
            return
        key = self._keys.setdefault(key, key)
        publish: int | None = None
        attachment = sample.attachment
        if attachment is not None:
            raw = attachment.to_bytes()
            if len(raw) == 8:
                publish = int.from_bytes(raw, "little")
        self._offer((key, sample.payload.to_bytes(), rx_ns, publish))

    def _on_token(self, key: str, alive: bool, rx_ns: int) -> None:
        if self._closing:
            return
        with self._lock:
            seq = self._seq
            self._seq += 1
        change = LivelinessChange.from_token(
            key, self.node.keys.suffix(key), alive=alive, stamp_ns=rx_ns, seq=seq
        )
        self._offer((self._liveliness_key, change.encode(), rx_ns, None))

    def _work(self) -> None:
        while True:
            try:
                item = self._queue.get(timeout=0.1)
            except queue.Empty:
                self._write(self.core.tick(now_ns()))
                continue
            if item is None:
                break
            with self._lock:
                self._queued -= len(item[1]) + ENTRY_OVERHEAD
            self._write(self.core.on_sample(*item))
        dump = self.core.flush()
        if dump is not None:
            self._write([dump])

    def _write(self, dumps: list[Dump]) -> None:
        for dump in dumps:
            path = self.out_dir / dump_name(dump)
            started = time.perf_counter()
            try:
                n = write_dump(dump, path, self.prefix)
            except Exception:
                self.write_errors += 1
                log.exception("flight recorder: cannot write %s", path)
                continue
            self.files.append(path)
            reasons = ", ".join(f"{t.kind} ({t.detail})" for t in dump.triggers)
            took = (time.perf_counter() - started) * 1e3
            log.warning(
                "flight recorder: %s: %d messages (written in %.0f ms), triggered by %s",
                path,
                n,
                took,
                reasons,
            )

    def stats(self) -> dict[str, object]:
        """Counters of the core and the shell."""
        return {
            **self.core.stats.__dict__,
            "dropped": self.dropped,
            "queue_bytes": self.queue_bytes,
            "queue_peak_bytes": self.queue_peak,
            "write_errors": self.write_errors,
            "files": [str(p) for p in self.files],
        }

    def close(self) -> None:
        """Stop listening; write a dump still collecting; stop the worker."""
        self._closing = True
        self.node.close()
        self._queue.put(None)
        self._thread.join()

    def __enter__(self) -> FlightShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
