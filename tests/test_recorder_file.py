"""Recordings on disk: channels, schemas, counts, time order, CRCs, recovery of a cut file."""

from __future__ import annotations

import io
import json
import signal
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from mcap.reader import SeekingReader
from mcap.records import DataEnd
from mcap.stream_reader import StreamReader

from manus_stack.cli import main
from manus_stack.controlled import ControlledArm
from schemas.base import Message
from schemas.commands import ArmCommand
from schemas.keys import channel_type
from services.recorder.errors import RecordingError
from services.recorder.journal import journal_path
from services.recorder.reading import Recorded, Recording, decode
from services.recorder.recover import recover
from services.recorder.writer import RecordingWriter
from services.simulator.config import SimConfig

Published = list[tuple[int, str, Message]]


@pytest.fixture(scope="module")
def published() -> Published:
    """Every message of 3 s of a simulated arm (simulator + bridge + controller cores)."""
    arm = ControlledArm(SimConfig(start_pose="unfolded"))
    arm.start()
    arm.ls.run_for(3.0)
    return list(arm.ls.messages)


def _write(path: Path, messages: Published, flush_interval_ns: int = 250_000_000) -> None:
    with RecordingWriter(
        path, prefix="arm1", source="test", flush_interval_ns=flush_interval_ns
    ) as writer:
        for t, suffix, msg in messages:
            writer.write(suffix, msg, t)


def test_recording_reads_back_with_channels_schemas_counts_and_order(
    tmp_path: Path, published: Published
) -> None:
    path = tmp_path / "run.mcap"
    _write(path, published)
    # The whole file, data-section CRC and every chunk CRC checked.
    records = list(StreamReader(io.BytesIO(path.read_bytes()), validate_crcs=True).records)
    assert any(isinstance(r, DataEnd) and r.data_section_crc != 0 for r in records)

    rec = Recording(path)
    info = rec.info
    want = Counter(suffix for _, suffix, _ in published)
    assert {"state/joints", "state/status", "state/bridge", "can/rx", "can/tx"} <= set(want)
    assert info.prefix == "arm1" and info.source == "test"
    assert {c.suffix: c.messages for c in info.channels.values()} == dict(want)
    assert info.messages == len(published)
    assert info.chunks > 1  # 250 ms chunks over 3+ s
    for key, channel in info.channels.items():
        msg_type = channel_type(channel.suffix)
        assert msg_type is not None
        assert key == f"arm1/{channel.suffix}"
        assert channel.message_encoding == "msgpack"
        assert channel.schema_name == msg_type.TYPE_NAME
        assert channel.schema == json.loads(json.dumps(msg_type.json_schema()))

    got: list[tuple[Recorded, Message]] = list(rec.decoded())
    assert [r.log_ns for r, _ in got] == sorted(t for t, _, _ in published)
    # Same messages, same order (the publication order is a log-time order).
    assert [(r.suffix, m) for r, m in got] == [(s, m) for _, s, m in published]
    sequences: dict[str, list[int]] = {}
    for r, m in got:
        sequences.setdefault(r.suffix, []).append(r.sequence)
        stamp = getattr(m, "stamp_ns", None)
        assert r.publish_ns == (stamp if stamp is not None else r.log_ns)
    assert all(seq == list(range(len(seq))) for seq in sequences.values())


def test_a_damaged_chunk_fails_its_crc(tmp_path: Path, published: Published) -> None:
    path = tmp_path / "run.mcap"
    _write(path, published)
    with path.open("rb") as f:
        summary = SeekingReader(f).get_summary()
    assert summary is not None
    chunk = summary.chunk_indexes[1]
    data = bytearray(path.read_bytes())
    data[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0xFF  # in its compressed data
    path.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"run\.mcap"):
        list(Recording(path).messages())


def test_unknown_keys_and_bad_payloads_are_recorded_with_a_permissive_schema(
    tmp_path: Path,
) -> None:
    path = tmp_path / "odd.mcap"
    with RecordingWriter(path, prefix="p") as writer:
        writer.write_payload("p/someone/else", b"\xc1not msgpack", 5)
        writer.write_payload("p/trace/bridge/command/request", ArmCommand("stop").encode(), 7, 3)
        assert writer.stats.not_msgpack == 1
    rec = Recording(path)
    assert rec.info.channels["p/someone/else"].schema_name == "manus/Unknown"
    assert rec.info.channels["p/trace/bridge/command/request"].schema_name == "manus/ArmCommand/1"
    odd, trace = list(rec.messages())
    assert odd.payload == b"\xc1not msgpack" and odd.publish_ns == 5
    assert trace.publish_ns == 3 and decode(trace) == ArmCommand("stop")
    with pytest.raises(RecordingError, match="someone/else #0: no message type"):
        decode(odd)


def test_writer_rejects_bad_settings_and_writes_after_close(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="compression 'lz5'"):
        RecordingWriter(tmp_path / "x.mcap", compression="lz5")
    writer = RecordingWriter(tmp_path / "y.mcap")
    writer.close()
    with pytest.raises(RecordingError, match="already closed"):
        writer.write_payload("manus/estop", b"\x80", 1)
    with pytest.raises(RecordingError, match="not an MCAP file"):
        Recording(Path(__file__))


@pytest.mark.parametrize("fraction", [0.35, 0.8, 0.999])
def test_a_truncated_file_is_recovered(
    tmp_path: Path, published: Published, fraction: float
) -> None:
    whole = tmp_path / "whole.mcap"
    _write(whole, published)
    data = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(RecordingError, match="--recover"):
        Recording(cut)
    fixed = tmp_path / "fixed.mcap"
    stats = recover(cut, fixed)
    original = list(Recording(whole).messages())
    rescued = list(Recording(fixed).messages())
    assert stats.messages == len(rescued) > 0 and stats.bad_chunks == 0
    assert Recording(fixed).info.prefix == "arm1"
    # What survives is exactly the beginning of the recording ...
    assert rescued == original[: len(rescued)]
    # ... and what is lost is at most the chunk being written (250 ms) plus the one cut.
    lost = original[len(rescued) :]
    if fraction > 0.99:
        assert not lost or lost[-1].log_ns - lost[0].log_ns <= 2 * 250_000_000


def test_unclosed_writer_loses_only_the_open_chunk(tmp_path: Path, published: Published) -> None:
    path = tmp_path / "crash.mcap"
    with path.open("wb") as stream:
        writer = RecordingWriter(stream, flush_interval_ns=250_000_000)
        for t, suffix, msg in published:
            writer.write(suffix, msg, t)
        # No writer.close(): as if the process died now. The file holds every closed chunk.
    rescued = list(Recording(_recovered(path, tmp_path)).messages())
    end = published[-1][0]
    assert len(rescued) < len(published)
    assert all(t <= rescued[-1].log_ns for t, _, _ in published[: len(rescued)])
    assert end - rescued[-1].log_ns <= 250_000_000


def _recovered(path: Path, tmp_path: Path) -> Path:
    out = tmp_path / "recovered.mcap"
    recover(path, out)
    return out


def test_manus_record_recover_command(
    tmp_path: Path, published: Published, capsys: pytest.CaptureFixture[str]
) -> None:
    whole = tmp_path / "r.mcap"
    _write(whole, published)
    (tmp_path / "c.mcap").write_bytes(whole.read_bytes()[:-5000])
    assert main(["record", "--recover", str(tmp_path / "c.mcap")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["output"] == str(tmp_path / "c.recovered.mcap")
    assert Recording(out["output"]).info.messages == out["messages"] > 0
    assert main(["record", "--recover", str(tmp_path / "missing.mcap")]) == 1
    assert "missing.mcap" in capsys.readouterr().err


_KILLED = """
import os, signal, sys
import msgpack
from services.recorder.writer import RecordingWriter
w = RecordingWriter(sys.argv[1], prefix="arm1", journal=True)
for i in range(200):
    w.write_payload(f"arm1/k{i % 3}", msgpack.packb({"i": i}), 10**9 + i * 10**7)
if sys.argv[2] == "flushed":  # the chunk reached the file, the journal was not emptied yet
    w._writer.flush()
os.kill(os.getpid(), signal.SIGKILL)
"""


@pytest.mark.parametrize("when", ["open", "flushed"])
def test_a_killed_journalled_recorder_loses_nothing(tmp_path: Path, when: str) -> None:
    path = tmp_path / "killed.mcap"
    done = subprocess.run([sys.executable, "-c", _KILLED, str(path), when], check=False)
    assert done.returncode == -signal.SIGKILL
    assert journal_path(path).exists()
    fixed = tmp_path / "fixed.mcap"
    stats = recover(path, fixed)
    rescued = list(Recording(fixed).messages())
    assert stats.messages == len(rescued) == 200
    assert sorted(r.log_ns for r in rescued) == [10**9 + i * 10**7 for i in range(200)]
    assert {r.key for r in rescued} == {"arm1/k0", "arm1/k1", "arm1/k2"}
    assert (stats.from_journal > 0) == (when == "open")


def test_a_closed_recording_leaves_no_journal(tmp_path: Path, published: Published) -> None:
    path = tmp_path / "closed.mcap"
    with RecordingWriter(path, journal=True) as writer:
        for t, suffix, msg in published:
            writer.write(suffix, msg, t)
        assert journal_path(path).exists()
    assert not journal_path(path).exists()
    assert Recording(path).info.messages == len(published)
