"""The tests' Foxglove client subscribes again, a bounded number of times, to a channel
the server called unknown right after advertising it (the SDK's race:
``tests.foxglove_client.RESUBSCRIBE_S``); to nothing else."""

from __future__ import annotations

from typing import Any

from tests.foxglove_client import Received, _text

ADVERT = {"op": "advertise", "channels": [
    {"id": 2, "topic": "p/viz/tf", "encoding": "json", "schemaName": "x", "schema": ""},
    {"id": 3, "topic": "p/other", "encoding": "json", "schemaName": "x", "schema": ""},
]}  # fmt: skip


def _status(message: str) -> dict[str, Any]:
    return {"op": "status", "level": 2, "message": message}


def test_an_unknown_channel_just_advertised_is_subscribed_again_a_few_times() -> None:
    got, decoders = Received(), {}  # type: ignore[var-annotated]
    assert _text(ADVERT, got, ["p/viz/tf"], decoders) == [{"id": 1, "channelId": 2}]
    again = [_text(_status("Unknown channel ID: 2"), got, ["p/viz/tf"], decoders) for _ in range(5)]
    assert again[:3] == [[{"id": 1, "channelId": 2}]] * 3 and again[3:] == [[], []]
    assert got.resubscribed == 3 and len(got.statuses) == 5
    # a channel it never subscribed to, and any other status: nothing sent
    assert _text(_status("Unknown channel ID: 3"), got, ["p/viz/tf"], decoders) == []
    assert _text(_status("Unknown channel ID: 987654"), got, ["p/viz/tf"], decoders) == []
    assert _text(_status("something else"), got, ["p/viz/tf"], decoders) == []
