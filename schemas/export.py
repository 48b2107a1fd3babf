"""JSON Schema export: the language-neutral description of the bus messages.

:func:`channel_documents` gives one JSON Schema (draft 2020-12) per message type of
:func:`schemas.keys.channel_types`; ``manus schemas --out DIR`` writes them with an
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
from schemas.commands import EStop
from schemas.control import GoalAck
from schemas.jog import JogCommand, JogLevel, JogState
from schemas.sequencing import SubmitReply, Task, TaskControl, TaskEvent, TaskStatus

SUPERVISOR_FILE = Path(__file__).with_name("supervisor.schema.json")
"""The checked-in supervisor API document."""

SUPERVISOR_KEYS: dict[str, dict[str, str]] = {
    "sequencer/submit": {"kind": "queryable", "request": "Task", "reply": "SubmitReply",
                         "doc": "validate a whole task and start it; reply: id or every error"},
    "sequencer/control": {"kind": "queryable", "request": "TaskControl", "reply": "TaskStatus",
                          "doc": "cancel, pause, resume (or status of) the task"},
    "sequencer/status": {"kind": "queryable", "request": "TaskControl", "reply": "TaskStatus",
                         "doc": "where the current task stands (action: status)"},
    "sequencer/events": {"kind": "publication", "type": "TaskEvent",
                         "doc": "accepted, step_started/progress/finished/failed, paused, "
                                "resumed, cancelled, succeeded, failed"},
    "estop": {"kind": "publication (to publish)", "type": "EStop",
              "doc": "emergency stop: the bridge latches it; the running task fails"},
    "jog": {"kind": "publication (to publish)", "type": "JogCommand",
            "doc": "live control at 10-50 Hz: twist, joint or gripper speeds; the controller's "
                   "deadman (150 ms) stops the arm when it stops coming; a running task "
                   "pauses (user took over)"},
    "controller/jog_level": {"kind": "queryable", "request": "JogLevel", "reply": "GoalAck",
                             "doc": "set the jog speed level (1..5)"},
    "controller/jog_state": {"kind": "publication", "type": "JogState",
                             "doc": "the jog as the controller runs it: level, slow-down "
                                    "and stop reasons, refusals, gripper pose"},
    "alive/<service>": {"kind": "liveliness token",
                        "doc": "one per running service: sequencer, planner, controller, "
                               "can_bridge, simulator, recorder"},
}  # fmt: skip
"""Keys of the supervisor API (after the prefix, default ``manus``)."""

SUPERVISOR_TYPES: tuple[type[Message], ...] = (
    Task, SubmitReply, TaskControl, TaskStatus, TaskEvent, EStop,
    JogCommand, JogLevel, JogState, GoalAck,
)  # fmt: skip


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
            "(a Zenoh get with the payload); the reply is a SubmitReply. Follow "
            "<prefix>/sequencer/events. Control with TaskControl on <prefix>/sequencer/control. "
            "Drive the arm live by publishing JogCommand on <prefix>/jog."
        ),
        "keys": SUPERVISOR_KEYS,
        "$defs": {cls.__name__: cls.json_schema() for cls in SUPERVISOR_TYPES},
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
