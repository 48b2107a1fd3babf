"""Seeded fuzzing at the core level (manus_stack.fuzz): every endpoint of channel_types()
and every CAN id the bridge reads, through decode and the lock-step cores; fixed seed,
bounded (a few seconds). Longer runs: ``manus bench fuzz``."""

from __future__ import annotations

import random

import pytest

from manus.errors import SchemaError
from manus_stack.fuzz import KINDS, payloads, run_fuzz
from manus_stack.fuzz_live import bad_payloads
from schemas.keys import channel_types


@pytest.mark.parametrize("channel", sorted(channel_types()))
def test_every_payload_decodes_or_is_a_schema_error(channel: str) -> None:
    cls = channel_types()[channel]
    rng = random.Random(0)
    kinds = set()
    for kind, data in payloads(cls, len(KINDS), rng):
        kinds.add(kind)
        try:
            cls.decode(data)
        except SchemaError:
            assert kind != "valid", f"{channel}: a valid example was refused"
    assert kinds == set(KINDS)
    assert len(bad_payloads(cls, 1, rng)) == 1


def test_cores_survive_fuzz_and_the_square_runs_after() -> None:
    report = run_fuzz(seed=0, per_endpoint=10, frames=600)
    assert report.crashes == []
    assert set(report.inputs) == set(channel_types())  # every endpoint, new ones included
    assert all(n == 10 for n in report.inputs.values())
    assert sum(report.decoded.values()) > 0  # some reach the cores (valid, other shapes)
    assert report.validated > 0  # tasks validated as the sequencer does
    counts = report.bridge_counts
    assert counts["garbled_frames"] + counts["other_node_frames"] > 0  # the CAN fuzz counted
    assert report.task_after == "succeeded"
