"""Recording in parts (by size, by duration) and key include/exclude patterns."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.stream_reader import StreamReader

from manus.node import Node
from manus.session import ZenohSettings
from services.recorder.errors import RecordingError
from services.recorder.reading import Recording
from services.recorder.shell import RecorderShell
from services.recorder.split import KeyFilter, SplitWriter
from tests.conftest import eventually, matched_publisher

SQUARE = Path(__file__).parent / "data" / "thesis_square.mcap"


def test_key_filter_patterns() -> None:
    f = KeyFilter(["state/*", "controller/**"], ["state/bridge"])
    assert f("state/joints") and f("state/status")
    assert not f("state/bridge")  # excluded wins
    assert f("controller/feedback") and f("controller/a/b")
    assert not f("can/rx") and not f("state/joints/extra")
    assert KeyFilter([], ["can/*"])("trace/planner/plan/request")
    assert not KeyFilter([], ["can/*"])("can/tx")
    with pytest.raises(RecordingError, match="empty"):
        KeyFilter([" "])


def _valid(path: Path) -> int:
    with path.open("rb") as f:
        assert list(StreamReader(f, validate_crcs=True).records)
    return Recording(path).info.messages


@pytest.mark.parametrize(("split_bytes", "split_s"), [(0, 5.0), (64 * 1024, 0.0)])
def test_split_parts_are_each_a_valid_recording(
    tmp_path: Path, split_bytes: int, split_s: float
) -> None:
    src = list(Recording(SQUARE).messages())
    writer = SplitWriter(tmp_path / "run.mcap", split_bytes=split_bytes, split_s=split_s)
    for m in src:
        writer.write_payload(m.key, m.payload, m.log_ns, m.publish_ns)
    stats = writer.close()
    assert len(writer.parts) >= 3, writer.parts
    assert [p.name for p in writer.parts][:2] == ["run_000.mcap", "run_001.mcap"]
    counts = [_valid(p) for p in writer.parts]
    assert sum(counts) == len(src) == stats.messages
    got = [r for p in writer.parts for r in Recording(p).messages()]
    assert [(r.key, r.log_ns, r.payload) for r in got] == [
        (m.key, m.log_ns, m.payload) for m in src
    ]
    for p in writer.parts[:-1]:
        info = Recording(p).info
        if split_s:
            assert info.end_ns - info.start_ns < split_s * 1e9
        else:  # closed once past the size: at most one chunk (64 KiB before zstd) more
            assert p.stat().st_size < split_bytes + 64 * 1024 + 16 * 1024


def test_split_refuses_nonsense(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="split size"):
        SplitWriter(tmp_path / "x.mcap", split_bytes=100)


def test_recorder_records_only_the_selected_keys(
    zenoh_settings: ZenohSettings, tmp_path: Path
) -> None:
    prefix = zenoh_settings.prefix
    out = tmp_path / "sel.mcap"
    keys = KeyFilter(["state/*", "liveliness"], ["state/bridge"])
    with RecorderShell(zenoh_settings, out, keys=keys) as shell, Node("pub", zenoh_settings) as n:
        # every sample counted: publish once the recorder's subscription reached the
        # router, and wait for room rather than drop under load
        pubs = {s: matched_publisher(n.session, f"{prefix}/{s}", block=True) for s in
                ("state/joints", "state/bridge", "can/rx")}  # fmt: skip
        for m in Recording(SQUARE).messages(["state/joints", "state/bridge", "can/rx"]):
            pubs[m.suffix].put(m.payload)
        eventually(lambda: shell.received >= 347, 10.0, "joint states recorded")
        eventually(lambda: shell.filtered >= 351 + 1044, 10.0, "the rest filtered")
    info = Recording(out).info
    assert {c.suffix for c in info.channels.values()} == {"state/joints", "liveliness"}
    assert info.channels[f"{prefix}/state/joints"].messages == 347
