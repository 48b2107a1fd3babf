"""Recording in parts, and choosing what to record (what rosbag2 users expect).

:class:`SplitWriter` writes like :class:`~services.recorder.writer.RecordingWriter` but
starts a new file when the current part reaches ``split_bytes`` on disk or spans
``split_s`` seconds of log time: ``run.mcap`` becomes ``run_000.mcap``, ``run_001.mcap``,
... each a complete recording of its own (summary, CRCs, the ``manus`` metadata, its own
channels), readable alone.

:class:`KeyFilter` selects keys by suffix with ``--include`` / ``--exclude`` patterns in
the key-expression style of ``manus replay --only``: ``*`` matches within one level
(``state/*``), ``**`` any number of levels (``trace/**``), anything else literally; a key
is recorded when it matches an include pattern (or there is none) and no exclude pattern.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from services.recorder.errors import RecordingError
from services.recorder.writer import (
    DEFAULT_CHUNK_SIZE,
    DEFAULT_FLUSH_INTERVAL_NS,
    ChannelStats,
    RecordingWriter,
    WriterStats,
)


def _regex(pattern: str) -> re.Pattern[str]:
    parts = []
    for chunk in re.split(r"(\*\*|\*)", pattern):
        if chunk == "**":
            parts.append(".*")
        elif chunk == "*":
            parts.append("[^/]*")
        else:
            parts.append(re.escape(chunk))
    return re.compile("".join(parts))


class KeyFilter:
    """Include / exclude patterns over key suffixes (see the module docstring).

    Raises:
        RecordingError: an empty pattern.
    """

    def __init__(self, include: Sequence[str] = (), exclude: Sequence[str] = ()) -> None:
        for p in (*include, *exclude):
            if not p.strip():
                raise RecordingError("an empty --include/--exclude pattern matches nothing")
        self.include = [_regex(p) for p in include]
        self.exclude = [_regex(p) for p in exclude]
        self._cache: dict[str, bool] = {}

    def __call__(self, suffix: str) -> bool:
        """Whether ``suffix`` is recorded."""
        keep = self._cache.get(suffix)
        if keep is None:
            keep = (not self.include or any(r.fullmatch(suffix) for r in self.include)) and not any(
                r.fullmatch(suffix) for r in self.exclude
            )
            self._cache[suffix] = keep
        return keep


class SplitWriter:
    """A recording in parts (see the module docstring).

    Args:
        output: the recording's name; parts are ``<stem>_NNN<suffix>`` beside it.
        split_bytes: start a new part once the current one reaches this size [B] (0: never).
        split_s: ... or spans this much log time [s] (0: never).
        prefix, chunk_size, flush_interval_ns, source: as :class:`RecordingWriter`.

    Attributes:
        parts: the files so far, in order.
        stats: totals over every part.
    """

    def __init__(
        self,
        output: str | Path,
        *,
        split_bytes: int = 0,
        split_s: float = 0.0,
        prefix: str = "manus",
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        flush_interval_ns: int = DEFAULT_FLUSH_INTERVAL_NS,
        source: str = "",
    ) -> None:
        if split_bytes < 0 or split_s < 0 or (split_bytes and split_bytes < 64 * 1024):
            raise RecordingError(
                f"split size {split_bytes} B must be 0 or >= 65536, duration {split_s} s >= 0"
            )
        self.base = Path(output)
        self.split_bytes = split_bytes
        self.split_ns = round(split_s * 1e9)
        self.prefix = prefix
        self.chunk_size = chunk_size
        self.flush_interval_ns = flush_interval_ns
        self.source = source
        self.parts: list[Path] = []
        self.stats = WriterStats()
        self._start_ns: int | None = None
        self._current = self._open()
        self.closed = False

    @property
    def path(self) -> str:
        """The part being written."""
        return str(self.parts[-1])

    def _open(self) -> RecordingWriter:
        path = self.base.with_name(f"{self.base.stem}_{len(self.parts):03d}{self.base.suffix}")
        self.parts.append(path)
        self._start_ns = None
        return RecordingWriter(
            path,
            prefix=self.prefix,
            chunk_size=self.chunk_size,
            flush_interval_ns=self.flush_interval_ns,
            source=self.source,
        )

    def _due(self, log_ns: int) -> bool:
        if self._start_ns is None:
            return False
        if self.split_ns and log_ns - self._start_ns >= self.split_ns:
            return True
        return bool(self.split_bytes) and self._current.tell() >= self.split_bytes

    def write_payload(
        self, key: str, payload: bytes, log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """As :meth:`RecordingWriter.write_payload`, in the current part (a new one when
        the current one is full)."""
        if self._due(log_time_ns):
            self._current.close()
            self._current = self._open()
        before = self._current.stats.not_msgpack
        self._current.write_payload(key, payload, log_time_ns, publish_time_ns)
        if self._start_ns is None:
            self._start_ns = log_time_ns
        st = self.stats
        st.messages += 1
        st.bytes += len(payload)
        st.not_msgpack += self._current.stats.not_msgpack - before
        ch = st.channels.setdefault(key, ChannelStats())
        ch.messages += 1
        ch.bytes += len(payload)

    def tick(self, now_ns: int) -> None:
        """As :meth:`RecordingWriter.tick`."""
        self._current.tick(now_ns)

    def flush(self) -> None:
        """As :meth:`RecordingWriter.flush`."""
        self._current.flush()

    def close(self) -> WriterStats:
        """Close the current part."""
        if not self.closed:
            self.closed = True
            self._current.close()
        return self.stats
