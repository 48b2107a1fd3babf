"""Exports of a recording: JSON-encoded MCAP for Foxglove, candump ``.log`` for CAN tools.

Foxglove decodes JSON with JSON Schema but not MessagePack, so
:func:`export_json` rewrites every channel with the ``json`` message encoding and the same
JSON Schema; ``bytes`` fields become base64 strings, as the schemas say
(``contentEncoding: base64``). Times, sequences and channel names are kept. Given a
``view`` (:class:`View`: the viewer's core, passed in by ``manus export``, since a service
never imports another), it also writes what the live viewer shows, in Foxglove's own
schemas (the arm's link transforms, paths, log), so the file opens with the arm moving.

:func:`export_candump` writes the raw frames of ``can/rx`` (from the arm) and ``can/tx``
(sent by the bridge) with python-can's ``can.Logger`` (the format follows the file
name: ``.log`` is ``candump -L``; ``.asc`` and ``.blf`` work too), stamped with each
frame's CAN time, received frames marked ``R`` and sent ones ``T``.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import can
import msgpack
from mcap.well_known import MessageEncoding, SchemaEncoding
from mcap.writer import CompressionType, Writer

from schemas import endpoints as ep
from schemas.state import CanFrame
from services.recorder.errors import RecordingError
from services.recorder.reading import Recording, decode
from services.recorder.writer import LIBRARY, METADATA_NAME

CAN_SUFFIXES = (ep.CAN_RX, ep.CAN_TX)


def _jsonable(value: Any) -> Any:
    if isinstance(value, bytes | bytearray):
        return base64.b64encode(bytes(value)).decode("ascii")
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    return value


class _Schema(Protocol):
    @property
    def name(self) -> str: ...
    @property
    def encoding(self) -> str: ...
    @property
    def data(self) -> bytes: ...


class ViewMessage(Protocol):
    """A message of another format to add (``services.viewer.core.FoxMessage``)."""

    @property
    def topic(self) -> str: ...
    @property
    def schema(self) -> _Schema: ...
    @property
    def encoding(self) -> str: ...
    @property
    def data(self) -> bytes: ...
    @property
    def log_ns(self) -> int: ...


class View(Protocol):
    """Turns recorded samples into more channels (``services.viewer.core.ViewerCore``)."""

    def describe(self, t_ns: int) -> Iterable[ViewMessage]: ...

    def on_sample(self, key: str, payload: bytes, t_ns: int) -> Iterable[ViewMessage]: ...


@dataclass(frozen=True)
class ExportStats:
    """What an export wrote.

    Attributes:
        messages: messages (or frames) written.
        skipped: messages that could not be converted (not MessagePack, bad frame).
        view_messages: messages the view added.
    """

    messages: int
    skipped: int
    view_messages: int = 0


def export_json(src: str | Path, dst: str | Path, view: View | None = None) -> ExportStats:
    """Write ``src`` again as an MCAP with JSON-encoded messages (opens in Foxglove), and
    with ``view``, the channels it makes of them (those not recorded already).

    Raises:
        RecordingError: ``src`` cannot be read or ``dst`` cannot be written.
    """
    rec = Recording(src)
    try:
        out = open(dst, "wb")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise RecordingError(f"{dst}: cannot create: {exc}") from exc
    written = skipped = 0
    with out:
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(library=LIBRARY + " (json export)")
        writer.add_metadata(METADATA_NAME, {"prefix": rec.info.prefix, "source": rec.info.source})
        schema_ids: dict[str, int] = {}
        channel_ids: dict[str, int] = {}
        for key, info in rec.info.channels.items():
            sid = schema_ids.get(info.schema_name)
            if sid is None:
                data = json.dumps(info.schema, sort_keys=True).encode()
                sid = writer.register_schema(info.schema_name, SchemaEncoding.JSONSchema, data)
                schema_ids[info.schema_name] = sid
            channel_ids[key] = writer.register_channel(
                key, MessageEncoding.JSON, sid, {"suffix": info.suffix}
            )
        viewed: dict[str, tuple[int, list[int]]] = {}  # topic -> (channel id, [next seq])

        def add_view(vm: ViewMessage) -> None:
            if vm.topic in channel_ids:  # a recorded channel: already written
                return
            entry = viewed.get(vm.topic)
            if entry is None:
                sid = schema_ids.get(vm.schema.name)
                if sid is None:
                    sid = writer.register_schema(vm.schema.name, vm.schema.encoding, vm.schema.data)
                    schema_ids[vm.schema.name] = sid
                cid = writer.register_channel(vm.topic, vm.encoding, sid)
                entry = viewed[vm.topic] = (cid, [0])
            writer.add_message(entry[0], vm.log_ns, vm.data, vm.log_ns, entry[1][0])
            entry[1][0] += 1

        if view is not None:
            for vm in view.describe(rec.info.start_ns):
                add_view(vm)
        for msg in rec.messages():
            if view is not None:
                for vm in view.on_sample(msg.key, msg.payload, msg.log_ns):
                    add_view(vm)
            try:
                value = msgpack.unpackb(msg.payload, raw=False, strict_map_key=False)
            except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
                skipped += 1
                continue
            data = json.dumps(_jsonable(value), separators=(",", ":")).encode()
            writer.add_message(channel_ids[msg.key], msg.log_ns, data, msg.publish_ns, msg.sequence)
            written += 1
        writer.finish()  # type: ignore[no-untyped-call]
    return ExportStats(written, skipped, sum(seq[0] for _, seq in viewed.values()))


def frame_to_can(frame: CanFrame, *, received: bool, channel: str) -> can.Message:
    """A python-can message for a recorded frame (timestamp = its CAN time [s])."""
    return can.Message(
        timestamp=frame.stamp_ns / 1e9,
        arbitration_id=frame.id,
        is_extended_id=False,
        is_remote_frame=frame.remote,
        dlc=frame.dlc,
        data=b"" if frame.remote else frame.data,
        is_rx=received,
        channel=channel,
    )


def export_candump(src: str | Path, dst: str | Path, *, channel: str = "can0") -> ExportStats:
    """Write the raw CAN frames of ``src`` to ``dst`` with ``can.Logger``.

    Raises:
        RecordingError: ``src`` cannot be read, holds no ``can/rx``/``can/tx`` channel, or
            ``dst`` cannot be written.
    """
    rec = Recording(src)
    if not any(c.suffix in CAN_SUFFIXES for c in rec.info.channels.values()):
        raise RecordingError(
            f"{src}: no can/rx or can/tx channel to export (was a bridge running?)"
        )
    written = skipped = 0
    try:
        logger = can.Logger(str(dst))
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{dst}: cannot write a CAN log: {exc}") from exc
    try:
        for msg in rec.messages(CAN_SUFFIXES):
            try:
                frame = decode(msg)
            except RecordingError:
                skipped += 1
                continue
            assert isinstance(frame, CanFrame)
            logger(frame_to_can(frame, received=msg.suffix == ep.CAN_RX, channel=channel))
            written += 1
    finally:
        logger.stop()
    return ExportStats(written, skipped)
