"""The supervisor API's language-neutral description is current and describes real payloads."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import msgpack

from schemas.export import SUPERVISOR_FILE, channel_documents, dumps, supervisor_document
from schemas.keys import channel_types
from services.sequencer.taskfile import task_from_args

ROOT = Path(__file__).resolve().parent.parent


def test_checked_in_supervisor_schema_is_current() -> None:
    assert SUPERVISOR_FILE.read_text(encoding="utf-8") == dumps(supervisor_document()), (
        "schemas/supervisor.schema.json is out of date: run `manus schemas --update`"
    )


def test_supervisor_schema_validates_a_task_as_sent_on_the_wire() -> None:
    doc = json.loads(SUPERVISOR_FILE.read_text(encoding="utf-8"))
    task = task_from_args([str(ROOT / "paths" / "thesis_square.txt"), "40"])
    wire = msgpack.unpackb(task.encode(), raw=False)
    jsonschema.Draft202012Validator(doc["$defs"]["Task"]).validate(wire)
    bad = dict(wire, steps=[dict(wire["steps"][1], kind="teleport")])
    errors = list(jsonschema.Draft202012Validator(doc["$defs"]["Task"]).iter_errors(bad))
    assert errors and "'teleport' is not one of" in errors[0].message
    assert set(doc["keys"]) >= {"sequencer/submit", "sequencer/control", "sequencer/events"}


def test_every_channel_has_a_schema_file() -> None:
    docs = channel_documents()
    index = docs["index.json"]["channels"]
    assert set(index) == set(channel_types())
    for name in index.values():
        jsonschema.Draft202012Validator.check_schema(docs[name])
