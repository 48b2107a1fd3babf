"""JSON Schema export: the language-neutral description of the bus messages.

:func:`channel_documents` gives one JSON Schema (draft 2020-12) per message type of
:func:`schemas.keys.channel_types` (both derived from the endpoint table,
:mod:`schemas.endpoints`); ``manus schemas --out DIR`` writes them with an
``index.json`` (key suffix -> type). :func:`supervisor_document` is the supervisor's API
in one document (keys, kinds, and the message types under ``$defs``), checked in as
``schemas/supervisor.schema.json`` (a test keeps it current). Payloads are MessagePack
maps with exactly these fields; ``bytes`` fields are MessagePack ``bin``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from schemas.base import Message
from schemas.endpoints import TABLE, Audience, Kind

SUPERVISOR_FILE = Path(__file__).with_name("supervisor.schema.json")
"""The checked-in supervisor API document."""


def supervisor_keys() -> dict[str, dict[str, str]]:
    """Keys of the supervisor API (after the prefix, default ``manus``): the endpoints of
    the supervisor audience, from the endpoint table."""
    out: dict[str, dict[str, str]] = {}
    for e in TABLE:
        if e.audience is not Audience.SUPERVISOR:
            continue
        entry: dict[str, str] = {"kind": e.kind.value}
        if e.kind is Kind.QUERYABLE:
            assert e.msg_type is not None and e.reply_type is not None
            entry |= {"request": e.msg_type.__name__, "reply": e.reply_type.__name__}
        elif e.msg_type is not None:
            entry["type"] = e.msg_type.__name__
        entry["owner"] = e.owner
        entry["doc"] = e.doc
        out[e.pattern] = entry
    return out


def supervisor_types() -> list[type[Message]]:
    """The message types of the supervisor API, each once, in table order."""
    found: list[type[Message]] = []
    for e in TABLE:
        if e.audience is Audience.SUPERVISOR:
            for cls in (e.msg_type, e.reply_type):
                if cls is not None and cls not in found:
                    found.append(cls)
    return found


def file_name(cls: type[Message]) -> str:
    """``manus/Task/1`` -> ``manus.Task.1.schema.json``."""
    return cls.TYPE_NAME.replace("/", ".") + ".schema.json"


def channel_documents() -> dict[str, dict[str, Any]]:
    """File name -> JSON Schema of every message type on the bus, plus ``index.json``."""
    from schemas.keys import channel_types

    docs: dict[str, dict[str, Any]] = {}
    index: dict[str, str] = {}
    for suffix, cls in sorted(channel_types().items()):
        docs[file_name(cls)] = cls.json_schema()
        index[suffix] = file_name(cls)
    docs["index.json"] = {
        "description": "key suffix (after the prefix) -> JSON Schema file of its payload; "
        "'<key>#request' / '<key>#reply' are the two sides of a queryable. Payloads are "
        "MessagePack maps.",
        "channels": index,
    }
    return docs


def supervisor_document() -> dict[str, Any]:
    """The supervisor API in one JSON document."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": "manus/supervisor/1",
        "title": "Manus sequencer: the supervisor API",
        "description": (
            "Zenoh keys under a prefix (default 'manus'), MessagePack payloads (maps with "
            "exactly the fields below; SI units). Submit a Task to <prefix>/sequencer/submit "
            "(a Zenoh get with the payload); the reply is a SubmitReply. A task submitted "
            "while the bridge is still starting is held until it runs, at most the "
            "sequencer's bridge_wait_s (30 s by default): give the get a timeout longer "
            "than that plus 5 s per step. Follow "
            "<prefix>/sequencer/events. Control with TaskControl on <prefix>/sequencer/control."
        ),
        "keys": supervisor_keys(),
        "$defs": {cls.__name__: cls.json_schema() for cls in supervisor_types()},
    }


def dumps(doc: dict[str, Any]) -> str:
    """The canonical text of a document (2-space indent, final newline)."""
    return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"


def write_schemas(out_dir: str | Path) -> list[Path]:
    """Write every channel's schema, ``index.json`` and the supervisor document."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    docs = channel_documents()
    docs[SUPERVISOR_FILE.name] = supervisor_document()
    for name, doc in docs.items():
        path = out / name
        path.write_text(dumps(doc), encoding="utf-8")
        written.append(path)
    return written
