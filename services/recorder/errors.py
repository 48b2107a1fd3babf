"""The recorder's errors: one family under :class:`manus.errors.ManusError`."""

from __future__ import annotations

from manus.errors import ManusError


class RecordingError(ManusError):
    """An MCAP recording cannot be written, read, recovered or exported.

    Messages name the file, the channel or record concerned and what was expected.
    """
