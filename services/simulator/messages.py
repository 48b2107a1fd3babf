"""The arm's message channel: one (class, code) in each cycle's 0x350 status frame.

Priority (docs/protocol.md, Status byte: bits 7-6): a latched error, else a warning that
held during the cycle (the lowest code if several), else the oldest pending general message
(each general message is reported once: "gripper ready", "absolute angles measured", "arm
folded", "arm unfolded"), else none.
"""

from __future__ import annotations

from collections import deque

from manus.protocol import MessageClass


class MessageBoard:
    """Collects what happened since the last status frame and picks what it reports."""

    def __init__(self) -> None:
        self._general: deque[tuple[int, int]] = deque()
        self._warnings: set[int] = set()
        self.error: int | None = None
        """The latched error code, None when there is none."""

    def post_general(self, t_ns: int, code: int) -> None:
        """Queue a general message that becomes reportable at ``t_ns``."""
        self._general.append((t_ns, code))

    def raise_warnings(self, codes: set[int] | frozenset[int]) -> None:
        """Warnings that hold now (reported in the next status frame)."""
        self._warnings.update(codes)

    def latch_error(self, code: int) -> None:
        """An error: reported in every status frame until :meth:`clear_error`."""
        self.error = code

    def clear_error(self) -> None:
        """Forget the latched error (a 0x370 stop became active)."""
        self.error = None

    def take(self, t_ns: int) -> tuple[MessageClass, int]:
        """The message of the status frame sent at ``t_ns``; forgets the cycle's warnings."""
        warnings, self._warnings = self._warnings, set()
        if self.error is not None:
            return MessageClass.ERROR, self.error
        if warnings:
            return MessageClass.WARNING, min(warnings)
        if self._general and self._general[0][0] <= t_ns:
            return MessageClass.GENERAL, self._general.popleft()[1]
        return MessageClass.NONE, 0
