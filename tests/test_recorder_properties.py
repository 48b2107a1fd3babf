"""Properties of the recording format over random traffic: what is written reads back in
log-time order (ties in write order), each channel numbered 0, 1, 2, ...; a file cut
anywhere recovers to a prefix of what was written."""

from __future__ import annotations

import tempfile
from pathlib import Path

import msgpack
from hypothesis import given, settings
from hypothesis import strategies as st

from services.recorder.errors import RecordingError
from services.recorder.reading import Recording
from services.recorder.recover import recover
from services.recorder.writer import RecordingWriter

SUFFIXES = ("state/joints", "can/rx", "cmd/joint_velocity", "trace/planner/plan/reply", "x/y")

traffic = st.lists(
    st.tuples(
        st.sampled_from(SUFFIXES),
        st.integers(min_value=0, max_value=2_000_000_000),  # log time [ns]
        st.one_of(st.none(), st.integers(min_value=0, max_value=2**63)),  # stamp_ns
        st.binary(max_size=40),
    ),
    min_size=1,
    max_size=120,
)


def _payload(stamp: int | None, blob: bytes) -> bytes:
    body: dict[str, object] = {"blob": blob}
    if stamp is not None:
        body["stamp_ns"] = stamp
    return bytes(msgpack.packb(body, use_bin_type=True))


def _write(path: Path, items: list[tuple[str, int, int | None, bytes]]) -> None:
    with RecordingWriter(path, prefix="p", chunk_size=1024, flush_interval_ns=50_000_000) as w:
        for suffix, t, stamp, blob in items:
            w.write_payload(f"p/{suffix}", _payload(stamp, blob), t, publish_time_ns=t + 1)


@settings(max_examples=60)
@given(traffic)
def test_reads_back_in_log_time_order_with_channel_sequences(
    items: list[tuple[str, int, int | None, bytes]],
) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "r.mcap"
        _write(path, items)
        got = list(Recording(path).messages())
    order = sorted(range(len(items)), key=lambda i: items[i][1])  # stable: ties in write order
    assert [(r.suffix, r.log_ns, r.payload) for r in got] == [
        (items[i][0], items[i][1], _payload(items[i][2], items[i][3])) for i in order
    ]
    for r in got:
        stamp = msgpack.unpackb(r.payload).get("stamp_ns")
        assert r.publish_ns == (stamp if stamp is not None else r.log_ns + 1)
    for suffix in SUFFIXES:
        seqs = sorted(r.sequence for r in got if r.suffix == suffix)
        assert seqs == list(range(len(seqs)))


@settings(max_examples=40)
@given(traffic, st.floats(min_value=0.0, max_value=1.0))
def test_a_cut_file_recovers_to_a_prefix(
    items: list[tuple[str, int, int | None, bytes]], fraction: float
) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        whole, cut, fixed = (Path(tmp) / n for n in ("w.mcap", "c.mcap", "f.mcap"))
        _write(whole, items)
        data = whole.read_bytes()
        cut.write_bytes(data[: int(len(data) * fraction)] if fraction < 1.0 else data)
        try:
            stats = recover(cut, fixed)
        except RecordingError as exc:  # only a file cut inside its 8-byte magic is not MCAP
            assert len(data) * fraction < 8, exc
            return
        rescued = [(r.key, r.sequence, r.payload) for r in Recording(fixed).messages()]
        written = [(r.key, r.sequence, r.payload) for r in Recording(whole).messages()]
    assert stats.messages == len(rescued) and stats.bad_chunks == 0
    # Recovered messages are exactly the written ones of the complete chunks.
    assert set(rescued) <= set(written)
    for key in {k for k, _, _ in rescued}:
        seqs = sorted(s for k, s, _ in rescued if k == key)
        assert seqs == list(range(len(seqs)))  # a prefix of each channel
    if fraction == 1.0:
        assert sorted(rescued) == sorted(written)
