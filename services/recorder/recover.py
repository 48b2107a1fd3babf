"""Rescue a recording that was never closed (crash, power loss, ``kill -9``).

An MCAP file cut short has no summary and usually ends inside a record. :func:`recover`
walks the records from the start, keeps every complete one (schemas, channels, metadata,
and chunks whose CRC checks out), stops at the first incomplete or unreadable record, and
writes what it kept to a new, valid file with a summary. The open chunk of a recorder
killed outright is in its journal (``FILE.open``, :mod:`~services.recorder.journal`,
written by ``manus record``): its records that the complete part lacks are added (a
channel first seen there is made again from its key). Without a journal, what is lost is
the open chunk: up to :data:`~services.recorder.writer.DEFAULT_FLUSH_INTERVAL_NS`.
"""

from __future__ import annotations

import io
import struct
from dataclasses import dataclass
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import MAGIC_SIZE, StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from schemas.keys import Keys
from services.recorder.errors import RecordingError
from services.recorder.journal import journal_path, read_journal
from services.recorder.writer import LIBRARY, add_channel

_MAGIC = b"\x89MCAP0\r\n"
_RECORD_HEAD = 9  # opcode (1) + length (8)


@dataclass(frozen=True)
class RecoverStats:
    """What :func:`recover` kept and lost.

    Attributes:
        messages: messages written to the new file.
        chunks: complete chunks kept.
        bad_chunks: complete chunks dropped (CRC mismatch or undecodable).
        orphans: messages dropped because their channel record was lost.
        lost_bytes: bytes after the last complete record (the incomplete tail).
        end_ns: log time of the last message kept [ns] (0: none).
        from_journal: messages of those taken from the journal.
    """

    messages: int
    chunks: int
    bad_chunks: int
    orphans: int
    lost_bytes: int
    end_ns: int
    from_journal: int = 0


def _complete_prefix(data: bytes) -> int:
    """Length of the part of ``data`` made of the magic and complete records."""
    if data[:MAGIC_SIZE] != _MAGIC:
        raise RecordingError("not an MCAP file (bad magic)")
    pos = MAGIC_SIZE
    while pos + _RECORD_HEAD <= len(data):
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        end = pos + _RECORD_HEAD + length
        if end > len(data):
            break
        pos = end
    return pos


class _Copier:
    """Copies records to ``writer``, renumbering schemas and channels, counting messages."""

    def __init__(self, writer: Writer) -> None:
        self.writer = writer
        self.schemas: dict[int, int] = {}  # old id -> new id
        self.channels: dict[int, int] = {}
        self.messages = self.chunks = self.bad_chunks = self.orphans = 0
        self.end_ns = 0
        self.schema_ids: dict[str, int] = {}  # name -> new id
        self.topics: dict[str, int] = {}  # topic -> new channel id
        self.topic_of: dict[int, str] = {}  # new channel id -> topic
        self.kept: set[tuple[str, int, int]] = set()  # (topic, sequence, log time)

    def take(self, record: object) -> None:
        """One record of the source (a chunk's records one by one, not the chunk)."""
        writer = self.writer
        if isinstance(record, Schema):
            if record.id not in self.schemas:
                self.schemas[record.id] = writer.register_schema(
                    record.name, record.encoding, record.data
                )
                self.schema_ids.setdefault(record.name, self.schemas[record.id])
        elif isinstance(record, Channel):
            if record.id not in self.channels:
                sid = self.schemas.get(record.schema_id, 0)
                self.channels[record.id] = writer.register_channel(
                    record.topic, record.message_encoding, sid, dict(record.metadata)
                )
                self.topics.setdefault(record.topic, self.channels[record.id])
                self.topic_of[self.channels[record.id]] = record.topic
        elif isinstance(record, Message):
            cid = self.channels.get(record.channel_id)
            if cid is None:
                self.orphans += 1
                return
            writer.add_message(
                cid, record.log_time, record.data, record.publish_time, record.sequence
            )
            self.kept.add((self.topic_of[cid], record.sequence, record.log_time))
            self.messages += 1
            self.end_ns = max(self.end_ns, record.log_time)
        elif isinstance(record, Metadata):
            writer.add_metadata(record.name, dict(record.metadata))

    def take_all(self, reader: StreamReader) -> None:
        """Every record up to the first that does not read; chunks whose CRC fails are
        counted and skipped."""
        try:
            for record in reader.records:
                if not isinstance(record, Chunk):
                    self.take(record)
                    continue
                try:
                    inner = breakup_chunk(record, validate_crc=True)
                except (McapError, ValueError, EOFError, struct.error):
                    self.bad_chunks += 1
                    continue
                self.chunks += 1
                for rec in inner:
                    self.take(rec)
        except (McapError, ValueError, EOFError, struct.error):
            pass  # the end of the complete records (or a damaged one): keep what came before

    def take_journal(self, path: Path) -> int:
        """The journal's messages that are not in the file yet; how many."""
        prefix, entries = read_journal(path)
        keys, added = Keys(prefix), 0
        for e in entries:
            if (e.key, e.sequence, e.log_ns) in self.kept:
                continue  # its chunk reached the file before the journal was emptied
            cid = self.topics.get(e.key)
            if cid is None:
                cid = self.topics[e.key] = add_channel(self.writer, self.schema_ids, keys, e.key)
            self.writer.add_message(cid, e.log_ns, e.payload, e.publish_ns, e.sequence)
            self.kept.add((e.key, e.sequence, e.log_ns))
            self.messages += 1
            self.end_ns = max(self.end_ns, e.log_ns)
            added += 1
        return added


def recover(src: str | Path, dst: str | Path) -> RecoverStats:
    """Write the complete part of the recording ``src`` to ``dst`` (a valid MCAP file).

    Raises:
        RecordingError: ``src`` cannot be read or is not MCAP, or ``dst`` cannot be
            written.
    """
    try:
        data = Path(src).read_bytes()
    except OSError as exc:
        raise RecordingError(f"{src}: cannot read: {exc}") from exc
    try:
        end = _complete_prefix(data)
    except RecordingError as exc:
        raise RecordingError(f"{src}: {exc}") from exc
    reader = StreamReader(io.BytesIO(data[:end]), emit_chunks=True)
    try:
        out = open(dst, "wb")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise RecordingError(f"{dst}: cannot create: {exc}") from exc
    with out:
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(library=LIBRARY + " (recovered)")
        copier = _Copier(writer)
        copier.take_all(reader)
        journal = journal_path(src)
        journalled = copier.take_journal(journal) if journal.exists() else 0
        writer.finish()  # type: ignore[no-untyped-call]
    c = copier
    lost = len(data) - end
    return RecoverStats(c.messages, c.chunks, c.bad_chunks, c.orphans, lost, c.end_ns, journalled)
