"""The open chunk's journal: what a SIGKILL would otherwise take with it.

MCAP keeps the chunk being filled in memory until it is closed (at least every flush
interval), so a recorder killed outright loses up to that much of the bus. With a
journal, :class:`~services.recorder.writer.RecordingWriter` also appends each message,
as it is added, to ``FILE.mcap.open`` with one unbuffered ``write`` (the kernel keeps it
when the process dies; not a power loss), and empties the journal whenever a chunk
has been handed to the operating system. :func:`~services.recorder.recover.recover`
adds the journal's complete records that the file lacks; a clean close deletes it.

Format: a header line ``MANUSJ1 <prefix>\\n`` (the key prefix: channels first seen in the
open chunk are made again from their key), then records of ``<IQQQI`` (key length, log
time, publish time, sequence, payload length), the key (UTF-8) and the payload.
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

from services.recorder.errors import RecordingError

SUFFIX = ".open"
MAGIC = b"MANUSJ1 "
_HEAD = struct.Struct("<IQQQI")


def journal_path(recording: str | Path) -> Path:
    """Where the journal of ``recording`` lives."""
    return Path(f"{recording}{SUFFIX}")


@dataclass(frozen=True)
class Entry:
    """One journalled message."""

    key: str
    log_ns: int
    publish_ns: int
    sequence: int
    payload: bytes


class Journal:
    """The append-only journal of one recording's open chunk.

    Args:
        recording: the MCAP file whose journal this is.
        prefix: the recording's key prefix.
    """

    def __init__(self, recording: str | Path, prefix: str) -> None:
        self.path = journal_path(recording)
        flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND
        try:
            self._fd = os.open(self.path, flags, 0o644)
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot create the journal: {exc}") from exc
        self._header = MAGIC + prefix.encode() + b"\n"
        os.write(self._fd, self._header)

    def add(self, key: str, log_ns: int, publish_ns: int, sequence: int, payload: bytes) -> None:
        """Append one message (one ``write``: in the kernel when it returns)."""
        k = key.encode()
        head = _HEAD.pack(len(k), log_ns, publish_ns, sequence, len(payload))
        os.write(self._fd, head + k + payload)

    def clear(self) -> None:
        """Everything journalled is in the file: start again after the header."""
        os.ftruncate(self._fd, len(self._header))

    def close(self) -> None:
        """The recording is closed: delete the journal."""
        os.close(self._fd)
        self.path.unlink(missing_ok=True)


def read_journal(path: str | Path) -> tuple[str, list[Entry]]:
    """The prefix and the complete records of a journal (a torn last one is left out).

    Raises:
        RecordingError: the file cannot be read or is no journal.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read the journal: {exc}") from exc
    end = data.find(b"\n")
    if not data.startswith(MAGIC) or end < 0:
        raise RecordingError(f"{path}: not a recording journal (no {MAGIC!r} header line)")
    prefix = data[len(MAGIC) : end].decode()
    entries, pos = [], end + 1
    while pos + _HEAD.size <= len(data):
        n_key, log_ns, publish_ns, sequence, n_payload = _HEAD.unpack_from(data, pos)
        start = pos + _HEAD.size
        stop = start + n_key + n_payload
        if stop > len(data):
            break
        key = data[start : start + n_key].decode()
        entries.append(Entry(key, log_ns, publish_ns, sequence, data[start + n_key : stop]))
        pos = stop
    return prefix, entries
