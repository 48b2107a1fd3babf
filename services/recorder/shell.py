"""The recorder's live shell: everything under ``<prefix>/**`` into an MCAP file.

Zenoh callbacks only stamp each sample with its receive time and queue it; one writer
thread drains the queue into :class:`~services.recorder.writer.RecordingWriter`, so a
slow disk never blocks the bus, and closes a chunk at least every flush interval even
when the bus is quiet. Samples of the query mirrors (``trace/...``) carry the query's
receive time as their attachment, which becomes their publish time.

Liveliness tokens are not samples: a second subscriber sees each token under the prefix
appear (those already up when recording starts included, stamped with that moment) and
vanish, and each change is written as a :class:`~schemas.liveliness.LivelinessChange` on
the ``<prefix>/liveliness`` channel, log time = receive time, in the order received. The
recorder's own tokens are recorded too (its ``where`` token says which process wrote the
file). Samples published on ``<prefix>/liveliness`` itself are dropped and counted
(:attr:`RecorderShell.reserved_dropped`): that channel is the recorder's.
"""

from __future__ import annotations

import logging
import queue
import threading
from pathlib import Path

import zenoh

from manus.node import Node, now_ns
from manus.session import ZenohSettings
from schemas.liveliness import LIVELINESS, LivelinessChange
from services.recorder.split import KeyFilter, SplitWriter
from services.recorder.writer import (
    DEFAULT_CHUNK_SIZE,
    DEFAULT_FLUSH_INTERVAL_NS,
    RecordingWriter,
    WriterStats,
)

log = logging.getLogger("manus.recorder")

_Item = tuple[str, bytes, int, int | None]  # key, payload, receive time, publish time


class RecorderShell:
    """Records the bus of one arm (liveliness token ``<prefix>/alive/recorder``).

    Args:
        settings: how to reach the bus; its prefix selects the arm.
        output: the MCAP file to write.
        session: an open session to share (not closed by :meth:`close`).
        chunk_size: largest uncompressed chunk [bytes].
        flush_interval_ns: longest time a message waits in an open chunk [ns].
        split_bytes: write in parts of this size (``services.recorder.split``; 0: one file).
        split_s: ... or of this much time [s] (0: one file).
        keys: which key suffixes to record (None: all).

    Attributes:
        received: bus samples received.
        liveliness_changes: token changes received (appeared, vanished).
        reserved_dropped: samples published on ``<prefix>/liveliness`` and not recorded.
        filtered: samples and token changes left out by ``keys``.
        write_errors: items the writer could not record.
    """

    def __init__(
        self,
        settings: ZenohSettings,
        output: str | Path,
        *,
        session: zenoh.Session | None = None,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        flush_interval_ns: int = DEFAULT_FLUSH_INTERVAL_NS,
        split_bytes: int = 0,
        split_s: float = 0.0,
        keys: KeyFilter | None = None,
    ) -> None:
        self.writer: RecordingWriter | SplitWriter
        if split_bytes or split_s:
            self.writer = SplitWriter(
                output,
                split_bytes=split_bytes,
                split_s=split_s,
                prefix=settings.prefix,
                chunk_size=chunk_size,
                flush_interval_ns=flush_interval_ns,
                source="manus record",
            )
        else:
            self.writer = RecordingWriter(
                output,
                prefix=settings.prefix,
                chunk_size=chunk_size,
                flush_interval_ns=flush_interval_ns,
                source="manus record",
                journal=True,  # a SIGKILL loses nothing: ``recover`` reads FILE.open
            )
        self._keys = keys
        self.filtered = 0
        self._queue: queue.SimpleQueue[_Item | None] = queue.SimpleQueue()
        self._closing = False
        self._poll_s = min(flush_interval_ns / 4e9, 0.1)
        self.received = 0
        self.liveliness_changes = 0
        self.reserved_dropped = 0
        self._count_lock = threading.Lock()
        self.write_errors = 0
        self._thread = threading.Thread(target=self._drain, name="recorder-writer", daemon=True)
        self._thread.start()
        # Alive only once it listens: whoever waits for the recorder's token (manus up)
        # can start the rest knowing that their first messages are recorded.
        self.node = Node("recorder", settings, session=session, liveliness=False)
        self._liveliness_key = self.node.keys.liveliness
        self.node.subscribe_raw(self.node.keys.all, self._on_sample)
        self.node.watch_tokens(self.node.keys.all, self._on_token)
        self.node.announce()

    def _on_token(self, key: str, alive: bool, rx_ns: int) -> None:
        if self._closing:  # its own tokens vanish as it leaves: not part of the recording
            return
        suffix = self.node.keys.suffix(key)
        if self._keys is not None and not self._keys(LIVELINESS):
            with self._count_lock:
                self.filtered += 1
            return
        with self._count_lock:  # seq and queue order agree
            change = LivelinessChange.from_token(
                key, suffix, alive=alive, stamp_ns=rx_ns, seq=self.liveliness_changes
            )
            self.liveliness_changes += 1
            self._queue.put((self._liveliness_key, change.encode(), rx_ns, None))

    def _on_sample(self, sample: zenoh.Sample, rx_ns: int) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        key = str(sample.key_expr)
        if key == self._liveliness_key:
            with self._count_lock:
                self.reserved_dropped += 1
            return
        if self._keys is not None and not self._keys(self.node.keys.suffix(key)):
            with self._count_lock:
                self.filtered += 1
            return
        publish: int | None = None
        attachment = sample.attachment
        if attachment is not None:
            raw = attachment.to_bytes()
            if len(raw) == 8:
                publish = int.from_bytes(raw, "little")
        with self._count_lock:  # callbacks may run on several Zenoh threads
            self.received += 1
        self._queue.put((key, sample.payload.to_bytes(), rx_ns, publish))

    def _drain(self) -> None:
        while True:
            try:
                item = self._queue.get(timeout=self._poll_s)
            except queue.Empty:
                self.writer.tick(now_ns())
                continue
            if item is None:
                return
            try:
                self.writer.write_payload(*item)
            except Exception:
                self.write_errors += 1
                log.exception("recorder: cannot record a sample on %s", item[0])

    @property
    def recorded(self) -> int:
        """Messages written so far (samples and liveliness changes)."""
        return self.writer.stats.messages

    @property
    def samples_recorded(self) -> int:
        """Bus samples written so far (:attr:`recorded` without the liveliness changes)."""
        channel = self.writer.stats.channels.get(self._liveliness_key)
        return self.recorded - (channel.messages if channel is not None else 0)

    def close(self) -> WriterStats:
        """Stop listening, write what is queued, and close the file (summary and indexes)."""
        self._closing = True
        self.node.close()
        self._queue.put(None)
        self._thread.join()
        return self.writer.close()

    def __enter__(self) -> RecorderShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
