"""Reading recordings back: messages in log-time order, decoded to their types.

:class:`Recording` opens an MCAP file written by :class:`~services.recorder.writer.
RecordingWriter` (or any MCAP whose channels carry MessagePack under one key prefix).
Messages come in log-time order, ties in file order, so every reader (replay,
regression checks, plots, exports) sees the same sequence. Chunk CRCs are checked by
default.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, Schema

from manus.errors import SchemaError
from schemas.base import Message
from schemas.keys import channel_type
from services.recorder.errors import RecordingError
from services.recorder.writer import METADATA_NAME


class Recorded(NamedTuple):
    """One recorded message.

    Attributes:
        log_ns: receive time [ns].
        publish_ns: the message's stamp (or the query time of trace mirrors) [ns].
        sequence: index within its channel.
        key: full key expression.
        suffix: key after the prefix (``state/joints``).
        payload: the MessagePack bytes.
    """

    log_ns: int
    publish_ns: int
    sequence: int
    key: str
    suffix: str
    payload: bytes


@dataclass(frozen=True)
class ChannelInfo:
    """One channel of a recording.

    Attributes:
        key: full key expression (the MCAP topic).
        suffix: key after the prefix.
        schema_name: message type name (``manus/JointState/2``).
        schema: its JSON Schema.
        message_encoding: ``msgpack`` (or ``json`` for exports).
        messages: how many messages it holds (from the summary statistics).
    """

    key: str
    suffix: str
    schema_name: str
    schema: dict[str, Any]
    message_encoding: str
    messages: int


@dataclass(frozen=True)
class RecordingInfo:
    """What a recording holds (from its summary section).

    Attributes:
        path: the file.
        prefix: key prefix of the recorded arm.
        source: who wrote it.
        channels: key -> channel.
        messages: total message count.
        chunks: chunk count.
        start_ns: first log time [ns].
        end_ns: last log time [ns].
    """

    path: str
    prefix: str
    source: str
    channels: dict[str, ChannelInfo]
    messages: int
    chunks: int
    start_ns: int
    end_ns: int

    @property
    def duration_s(self) -> float:
        """Log-time span [s]."""
        return (self.end_ns - self.start_ns) / 1e9


def decode(rec: Recorded) -> Message:
    """The typed message of ``rec``.

    Raises:
        RecordingError: the key has no known type or the payload does not decode (naming
            the key, sequence and problem).
    """
    msg_type = channel_type(rec.suffix)
    if msg_type is None:
        raise RecordingError(f"{rec.key} #{rec.sequence}: no message type known for this key")
    try:
        return msg_type.decode(rec.payload)
    except SchemaError as exc:
        raise RecordingError(f"{rec.key} #{rec.sequence}: {exc}") from exc


class Recording:
    """A recording on disk.

    Args:
        path: the MCAP file.
        validate_crcs: check every chunk's CRC while reading.

    Raises:
        RecordingError: the file is missing, not MCAP, or has no summary (a crashed
            recording: recover it first with ``manus record --recover FILE``).
    """

    def __init__(self, path: str | Path, *, validate_crcs: bool = True) -> None:
        self.path = str(path)
        self.validate_crcs = validate_crcs
        self.info = self._read_info()

    def _reader(self, stream: Any) -> SeekingReader:
        try:
            return SeekingReader(stream, validate_crcs=self.validate_crcs)
        except (McapError, ValueError, EOFError) as exc:
            raise RecordingError(f"{self.path}: not an MCAP file: {exc}") from exc

    def _read_info(self) -> RecordingInfo:
        try:
            stream = open(self.path, "rb")  # noqa: SIM115 (closed below)
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot open: {exc}") from exc
        with stream:
            reader = self._reader(stream)
            try:
                summary = reader.get_summary()
                meta = {m.name: m.metadata for m in reader.iter_metadata()}
            except (McapError, ValueError, EOFError, struct.error) as exc:  # a cut record
                raise RecordingError(
                    f"{self.path}: unreadable summary ({exc}); if the recorder crashed, "
                    f"rescue it with: manus record --recover {self.path}"
                ) from exc
        if summary is None or summary.statistics is None:
            raise RecordingError(
                f"{self.path}: no summary section (the recording was not closed); rescue it "
                f"with: manus record --recover {self.path}"
            )
        stats = summary.statistics
        prefix = meta.get(METADATA_NAME, {}).get("prefix", "")
        channels = {
            ch.topic: _channel_info(
                ch,
                summary.schemas.get(ch.schema_id),
                prefix,
                stats.channel_message_counts.get(cid, 0),
            )
            for cid, ch in summary.channels.items()
        }
        return RecordingInfo(
            path=self.path,
            prefix=prefix,
            source=meta.get(METADATA_NAME, {}).get("source", ""),
            channels=channels,
            messages=stats.message_count,
            chunks=stats.chunk_count,
            start_ns=stats.message_start_time,
            end_ns=stats.message_end_time,
        )

    def messages(self, suffixes: Iterable[str] | None = None) -> Iterator[Recorded]:
        """Messages in log-time order (ties in file order), optionally only on ``suffixes``.

        Raises:
            RecordingError: a chunk fails its CRC or cannot be read.
        """
        wanted = None if suffixes is None else set(suffixes)
        topics = None
        if wanted is not None:
            topics = [c.key for c in self.info.channels.values() if c.suffix in wanted]
            if not topics:
                return
        with open(self.path, "rb") as stream:
            reader = self._reader(stream)
            suffix_of = {c.key: c.suffix for c in self.info.channels.values()}
            try:
                for _schema, channel, msg in reader.iter_messages(topics=topics):
                    yield Recorded(
                        msg.log_time,
                        msg.publish_time,
                        msg.sequence,
                        channel.topic,
                        suffix_of[channel.topic],
                        msg.data,
                    )
            except (McapError, ValueError, EOFError) as exc:
                raise RecordingError(f"{self.path}: cannot read a chunk: {exc}") from exc

    def decoded(self, suffixes: Iterable[str] | None = None) -> Iterator[tuple[Recorded, Message]]:
        """:meth:`messages` with each payload decoded to its type (see :func:`decode`)."""
        for rec in self.messages(suffixes):
            yield rec, decode(rec)


def _channel_info(channel: Channel, schema: Schema | None, prefix: str, count: int) -> ChannelInfo:
    suffix = channel.metadata.get("suffix", "")
    if not suffix:
        head = prefix + "/"
        suffix = channel.topic[len(head) :] if channel.topic.startswith(head) else channel.topic
    try:
        parsed = json.loads(schema.data) if schema is not None and schema.data else {}
    except ValueError:
        parsed = {}
    return ChannelInfo(
        key=channel.topic,
        suffix=suffix,
        schema_name=schema.name if schema is not None else "",
        schema=parsed if isinstance(parsed, dict) else {},
        message_encoding=channel.message_encoding,
        messages=count,
    )
