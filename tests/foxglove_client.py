"""A Foxglove WebSocket client for tests: the protocol the app speaks, over loopback.

It connects with the SDK's subprotocol, reads ``serverInfo`` and ``advertise``,
subscribes to topics, and collects ``messageData`` frames (opcode 1: subscription id
u32, log time u64, payload). Protobuf payloads are decoded with the schema the server
advertised (a FileDescriptorSet), JSON payloads with ``json``: nothing is taken from the
server's own code.
"""

from __future__ import annotations

import asyncio
import base64
import json
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import websockets
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from google.protobuf.json_format import MessageToDict

SUBPROTOCOL = "foxglove.sdk.v1"
"""The SDK 0.30 server's subprotocol (``foxglove.websocket.v1`` is refused)."""


@dataclass
class Received:
    """What a client got."""

    server_info: dict[str, Any] = field(default_factory=dict)
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)  # topic -> advertisement
    messages: dict[str, list[tuple[int, Any]]] = field(default_factory=dict)  # topic -> (t, msg)
    assets: dict[int, bytes | str] = field(default_factory=dict)  # request id -> data or error
    statuses: list[dict[str, Any]] = field(default_factory=list)
    subscribed: dict[int, int] = field(default_factory=dict)  # channel id -> subscription id
    resubscribed: int = 0
    """Subscriptions sent again after the server called their channel unknown (below)."""


UNKNOWN_CHANNEL = re.compile(r"Unknown channel ID: (\d+)")
RESUBSCRIBE_S = 0.05
"""How long to wait before subscribing again to a channel the server said it does not
know although it had just advertised it. The SDK's server (0.30, and its main branch on
2026-11-26: ``ConnectedClient::advertise_channels`` in rust/foxglove/src/websocket/
connected_client.rs) sends the ``advertise`` first and only then enters the channels in
the client's own map, which ``subscribe`` looks them up in: a client that answers fast
enough, or a server thread put off by a loaded machine between the two, meets "Unknown
channel ID". Seen once in the suite beside two CPU hogs (``test_stack_up``; ``manus view``
runs at niceness 10)."""


def protobuf_decoder(advert: dict[str, Any]) -> Callable[[bytes], dict[str, Any]]:
    """A decoder of a protobuf channel from its advertisement (schema = base64 FDS)."""
    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(advert["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for f in fds.file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(advert["schemaName"]))

    def decode(data: bytes) -> dict[str, Any]:
        out: dict[str, Any] = MessageToDict(
            cls.FromString(data),
            preserving_proto_field_name=True,
            always_print_fields_with_no_presence=True,
        )
        return out

    return decode


def decoder(advert: dict[str, Any]) -> Callable[[bytes], Any]:
    if advert["encoding"] == "protobuf":
        return protobuf_decoder(advert)
    return json.loads


Decoders = dict[int, tuple[str, Callable[[bytes], Any]]]


def _text(msg: dict[str, Any], got: Received, topics: list[str], decoders: Decoders) -> list[Any]:
    """Take in a JSON frame; the subscriptions to send for it."""
    op = msg.get("op")
    subs = []
    if op == "serverInfo":
        got.server_info = msg
    elif op == "advertise":
        for ch in msg["channels"]:
            got.channels[ch["topic"]] = ch
            if ch["topic"] in topics:
                sub = len(decoders) + 1
                decoders[sub] = (ch["topic"], decoder(ch))
                got.subscribed[ch["id"]] = sub
                subs.append({"id": sub, "channelId": ch["id"]})
    elif op == "status":
        got.statuses.append(msg)
        unknown = UNKNOWN_CHANNEL.fullmatch(str(msg.get("message", "")))
        channel = int(unknown.group(1)) if unknown else -1
        if channel in got.subscribed and got.resubscribed < 3 * len(got.subscribed):
            got.resubscribed += 1
            subs.append({"id": got.subscribed[channel], "channelId": channel})
    return subs


def _binary(frame: bytes, got: Received, decoders: Decoders) -> None:
    """Take in a binary frame: message data (1) or an asset (4)."""
    if frame[0] == 1:  # messageData: subscription id, log time, payload
        sub, log_ns = struct.unpack_from("<IQ", frame, 1)
        topic, decode = decoders[sub]
        got.messages.setdefault(topic, []).append((log_ns, decode(frame[13:])))
    elif frame[0] == 4:  # fetchAssetResponse: request id, status, error length
        request_id, status, err_len = struct.unpack_from("<IBI", frame, 1)
        body = frame[10:]
        got.assets[request_id] = body if status == 0 else body[:err_len].decode()


async def collect(
    url: str,
    topics: list[str],
    *,
    until: Callable[[Received], bool],
    timeout: float,
    assets: list[str] = (),  # type: ignore[assignment]
) -> Received:
    """Connect, subscribe to ``topics`` as they are advertised, fetch ``assets``, and
    collect until ``until(received)`` or ``timeout`` [s]."""
    got = Received()
    decoders: Decoders = {}
    protocols = [websockets.Subprotocol(SUBPROTOCOL)]
    async with websockets.connect(url, subprotocols=protocols, max_size=None) as ws:
        for i, uri in enumerate(assets):
            await ws.send(json.dumps({"op": "fetchAsset", "uri": uri, "requestId": i}))
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while not until(got) and loop.time() < deadline:
            try:
                frame = await asyncio.wait_for(ws.recv(), deadline - loop.time())
            except TimeoutError:
                break
            if isinstance(frame, str):
                msg = json.loads(frame)
                subs = _text(msg, got, topics, decoders)
                if subs and msg.get("op") == "status":
                    await asyncio.sleep(RESUBSCRIBE_S)  # see RESUBSCRIBE_S
                if subs:
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            else:
                _binary(frame, got, decoders)
    return got
