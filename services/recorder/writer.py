"""Writing the bus to MCAP: one channel per key, a JSON Schema per message type.

Each key expression gets its own channel (topic = the full key, e.g.
``manus/state/joints``) with the registered ``msgpack`` message encoding and a
``jsonschema`` schema named after the message type (``Message.json_schema()`` of the type
:func:`schemas.keys.channel_type` gives for the key; a key outside the table gets a
permissive schema named ``manus/Unknown``; the recorder's ``<prefix>/liveliness`` channel
of token changes is typed like any other, ``schemas.liveliness``). Every message is stored
as the payload bytes that travelled on the bus, with

- log time: when the recorder received it [ns] (the simulated time in lock-step runs);
- publish time: the message's own ``stamp_ns`` when it has one, else the time passed by
  the caller (the query receive time of ``trace/...`` mirrors), else the log time;
- sequence: the message's index within its channel (0, 1, 2, ...), assigned here.

Chunks are small and closed at least every ``flush_interval_ns`` of log time (and on
:meth:`RecordingWriter.tick`), then flushed to the operating system: a crash loses at most
the open chunk, a fraction of a second. :func:`services.recorder.recover.recover` rescues
the complete chunks of a file that was never closed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import msgpack
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

from manus.session import DEFAULT_PREFIX
from schemas.base import Message
from schemas.keys import Keys, channel_type
from services.recorder.errors import RecordingError
from services.recorder.journal import Journal

PROFILE = ""
"""MCAP profile (none of the well-known ones applies to msgpack channels)."""
LIBRARY = "manus-stack recorder"
METADATA_NAME = "manus"
"""Name of the metadata record holding ``prefix`` and ``source``."""
UNKNOWN_SCHEMA = "manus/Unknown"
UNKNOWN_JSON_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": UNKNOWN_SCHEMA,
    "title": "Unknown",
    "description": "a payload on a key outside schemas.keys; recorded as it was, not validated",
}
DEFAULT_CHUNK_SIZE = 64 * 1024
"""Largest uncompressed chunk [bytes] before it is closed."""
DEFAULT_FLUSH_INTERVAL_NS = 250_000_000
"""Longest log-time span of the open chunk [ns] before it is closed and flushed."""


@dataclass
class ChannelStats:
    """What one channel received."""

    messages: int = 0
    bytes: int = 0


@dataclass
class WriterStats:
    """Totals of a recording."""

    messages: int = 0
    bytes: int = 0
    chunks_flushed: int = 0
    not_msgpack: int = 0
    channels: dict[str, ChannelStats] = field(default_factory=dict)


def stamp_of(payload: bytes) -> int | None:
    """``stamp_ns`` of a MessagePack map payload, None when it has none.

    Raises:
        ValueError: (or a msgpack error) the payload is not MessagePack.
    """
    data = msgpack.unpackb(payload, raw=False, strict_map_key=False)
    if isinstance(data, dict):
        stamp = data.get("stamp_ns")
        if isinstance(stamp, int) and not isinstance(stamp, bool) and stamp >= 0:
            return stamp
    return None


def add_channel(writer: Writer, schemas: dict[str, int], keys: Keys, key: str) -> int:
    """Register the channel of ``key`` (and its message type's schema, once per name in
    ``schemas``) with ``writer``; its channel id."""
    suffix = keys.suffix(key)
    msg_type = channel_type(suffix)
    name = msg_type.TYPE_NAME if msg_type is not None else UNKNOWN_SCHEMA
    sid = schemas.get(name)
    if sid is None:
        schema = msg_type.json_schema() if msg_type is not None else UNKNOWN_JSON_SCHEMA
        data = json.dumps(schema, sort_keys=True).encode()
        sid = schemas[name] = writer.register_schema(name, SchemaEncoding.JSONSchema, data)
    return writer.register_channel(
        topic=key,
        message_encoding=MessageEncoding.MessagePack,
        schema_id=sid,
        metadata={"suffix": suffix},
    )


class RecordingWriter:
    """An MCAP file being written.

    Args:
        output: file path or binary stream (a stream is not closed by :meth:`close`).
        prefix: key prefix of the recorded arm (stored in the ``manus`` metadata record,
            used to name channels from suffixes and to find message types).
        chunk_size: largest uncompressed chunk [bytes].
        flush_interval_ns: longest log-time span of a chunk [ns] before it is flushed.
        compression: ``"zstd"`` or ``"none"``.
        source: free text stored in the metadata (e.g. ``manus record``, ``lockstep``).
        journal: also journal the open chunk to ``FILE.open`` (a file path only), so that
            ``recover`` loses nothing of a killed recorder (:mod:`.journal`).
    """

    def __init__(
        self,
        output: str | Path | IO[bytes],
        *,
        prefix: str = DEFAULT_PREFIX,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        flush_interval_ns: int = DEFAULT_FLUSH_INTERVAL_NS,
        compression: str = "zstd",
        source: str = "",
        journal: bool = False,
    ) -> None:
        if compression not in ("zstd", "none"):
            raise RecordingError(f"compression {compression!r} is not 'zstd' or 'none'")
        if chunk_size < 1024 or flush_interval_ns <= 0:
            raise RecordingError(
                f"chunk_size {chunk_size} B must be >= 1024 and flush_interval_ns "
                f"{flush_interval_ns} must be > 0"
            )
        self.path = str(output) if isinstance(output, str | Path) else getattr(output, "name", "")
        self._own = isinstance(output, str | Path)
        if isinstance(output, str | Path):
            try:
                self._stream: IO[bytes] = open(output, "wb")  # noqa: SIM115 (closed by close())
            except OSError as exc:
                raise RecordingError(f"{output}: cannot create the recording: {exc}") from exc
        else:
            self._stream = output
        self.keys = Keys(prefix)
        self._writer = Writer(
            self._stream,
            chunk_size=chunk_size,
            compression=CompressionType.ZSTD if compression == "zstd" else CompressionType.NONE,
            enable_data_crcs=True,  # DataEnd carries the CRC of the whole data section
        )
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._writer.add_metadata(METADATA_NAME, {"prefix": prefix, "source": source})
        self._journal = Journal(self.path, prefix) if journal and self._own else None
        self._flush_interval = flush_interval_ns
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, list[int]]] = {}  # key -> (id, [next seq])
        self._chunk_start: int | None = None
        self.stats = WriterStats()
        self.closed = False

    # -- channels ------------------------------------------------------------------------

    def _channel(self, key: str) -> tuple[int, list[int]]:
        entry = self._channels.get(key)
        if entry is None:
            cid = add_channel(self._writer, self._schemas, self.keys, key)
            entry = self._channels[key] = (cid, [0])
            self.stats.channels[key] = ChannelStats()
        return entry

    def tell(self) -> int:
        """Bytes written to the output so far (the open chunk not included) [B]."""
        return self._stream.tell()

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """Add a metadata record (e.g. ``flight``: why a flight recording was written)."""
        self._writer.add_metadata(name, data)

    # -- writing -------------------------------------------------------------------------

    def write_payload(
        self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """Record one payload as received on ``key`` (a full key expression).

        Args:
            key: where it travelled, e.g. ``manus/state/joints``.
            payload: the bytes as they travelled (recorded even if they do not decode).
            log_time_ns: receive time [ns].
            publish_time_ns: used when the payload has no ``stamp_ns`` (None: log time).
        """
        if self.closed:
            raise RecordingError(f"{self.path}: recording already closed")
        try:
            stamp = stamp_of(payload)
        except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
            stamp = None
            self.stats.not_msgpack += 1
        if stamp is None:
            stamp = publish_time_ns if publish_time_ns is not None else log_time_ns
        self._add(key, payload, log_time_ns, stamp)

    def write(self, suffix: str, msg: Message, log_time_ns: int) -> None:
        """Record a message directly (no bus): lock-step runs, tests, tools.

        Args:
            suffix: the key after the prefix, such as ``state/joints``.
            msg: the message (encoded here as it would travel).
            log_time_ns: the time it was published [ns] (simulated time in lock-step).
        """
        key = self.keys(suffix)
        stamp = getattr(msg, "stamp_ns", None)
        self._add(key, msg.encode(), log_time_ns, stamp if isinstance(stamp, int) else log_time_ns)

    def _add(self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        if not 0 <= log_time_ns < 2**64:
            raise RecordingError(f"{self.path}: {key}: log time {log_time_ns} ns outside 0..2^64")
        if not 0 <= publish_time_ns < 2**64:  # a stamp from another clock: keep the log time
            publish_time_ns = log_time_ns
        cid, seq = self._channel(key)
        if (
            self._chunk_start is not None
            and log_time_ns - self._chunk_start >= self._flush_interval
        ):
            self.flush()
        self._writer.add_message(
            channel_id=cid,
            log_time=log_time_ns,
            data=payload,
            publish_time=publish_time_ns,
            sequence=seq[0],
        )
        if self._journal is not None:
            self._journal.add(key, log_time_ns, publish_time_ns, seq[0], payload)
        seq[0] += 1
        if self._chunk_start is None:
            self._chunk_start = log_time_ns
        st = self.stats.channels[key]
        st.messages += 1
        st.bytes += len(payload)
        self.stats.messages += 1
        self.stats.bytes += len(payload)

    def tick(self, now_ns: int) -> None:
        """Close and flush the open chunk if it is older than the flush interval at
        ``now_ns`` (call it periodically when the bus is quiet)."""
        if self._chunk_start is not None and now_ns - self._chunk_start >= self._flush_interval:
            self.flush()

    def flush(self) -> None:
        """Close the open chunk and hand everything written so far to the operating system."""
        if self._chunk_start is None:
            return
        self._writer.flush()  # type: ignore[no-untyped-call]
        if self._journal is not None:  # the chunk is the operating system's now
            self._journal.clear()
        self._chunk_start = None
        self.stats.chunks_flushed += 1

    def close(self) -> WriterStats:
        """Write the summary (indexes, statistics) and close the file."""
        if not self.closed:
            self.closed = True
            self._writer.finish()  # type: ignore[no-untyped-call]
            if self._own:
                self._stream.close()
            else:
                self._stream.flush()
            if self._journal is not None:
                self._journal.close()
        return self.stats

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
