"""Replay controls: the playback clock alone, then a live replay driven by ``manus playback``."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest

from manus.node import Node
from manus.session import ZenohSettings
from manus_stack.cli import main
from schemas.playback import PlaybackControl
from services.recorder.errors import RecordingError
from services.recorder.playback import Playback
from services.recorder.reading import Recording
from services.recorder.replay import Replayer, schedule
from tests.conftest import eventually

SQUARE = Path(__file__).parent / "data" / "thesis_square.mcap"
OFFSETS = [0.1 * i for i in range(11)]  # 0.0 .. 1.0 s


def _run(p: Playback, now: float, until: float, dt: float = 0.01) -> list[tuple[float, int]]:
    """Step a fake clock from ``now`` to ``until``, taking what is due: (time, index)."""
    out = []
    t = now
    while t <= until + 1e-9:
        due = p.due(t)
        while due is not None and due <= t + 1e-9:
            out.append((round(t, 3), p.take(t)))
            due = p.due(t)
        t += dt
    return out


def test_plays_at_the_recorded_pace_and_scaled() -> None:
    played = _run(Playback(OFFSETS), 10.0, 11.5)
    assert [i for _, i in played] == list(range(11))
    assert [t for t, _ in played] == pytest.approx([10.0 + o for o in OFFSETS], abs=0.011)
    fast = _run(Playback(OFFSETS, rate=2.0), 0.0, 1.0)
    assert fast[-1][0] == pytest.approx(0.5, abs=0.011)
    assert [i for _, i in _run(Playback(OFFSETS, rate=None), 0.0, 0.0)] == list(range(11))


def test_start_until_and_loop_select_what_plays() -> None:
    p = Playback(OFFSETS, start_s=0.25, until_s=0.55, loops=2)
    assert [i for _, i in _run(p, 0.0, 2.0)] == [3, 4, 5, 3, 4, 5]
    assert p.state == "finished"
    with pytest.raises(RecordingError, match="nothing to replay between 2 s"):
        Playback(OFFSETS, start_s=2.0)
    with pytest.raises(RecordingError, match="rate -1"):
        Playback(OFFSETS, rate=-1.0)


def test_pause_step_resume_seek_and_rate() -> None:
    p = Playback(OFFSETS, paused=True)
    assert _run(p, 0.0, 1.0) == []  # paused: nothing
    assert p.control(PlaybackControl(action="step"), 1.0).ok
    assert _run(p, 1.0, 2.0) == [(1.0, 0)]  # exactly one
    status = p.control(PlaybackControl(action="seek", value=0.5), 2.0)
    assert status.ok and status.position == pytest.approx(0.5) and status.state == "paused"
    p.control(PlaybackControl(action="resume"), 3.0)
    played = _run(p, 3.0, 3.25)
    assert [i for _, i in played] == [5, 6, 7]  # at once, then the recorded pace
    assert played[0][0] == 3.0 and played[2][0] == pytest.approx(3.2, abs=0.011)
    p.control(PlaybackControl(action="rate", value=0.5), 3.25)  # keeps the position (0.75 s)
    nxt = _run(p, 3.25, 4.0)
    assert nxt[0][1] == 8  # 0.8 s is 0.05 s of recording away: 0.1 s at 0.5x
    assert nxt[0][0] == pytest.approx(3.35, abs=0.011)
    refused = p.control(PlaybackControl(action="step"), 4.0)
    assert not refused.ok and "only while paused" in refused.message
    assert not p.control(PlaybackControl(action="seek", value=5.0), 4.0).ok
    assert not p.control(PlaybackControl(action="rate", value=0.0), 4.0).ok


@pytest.mark.slow
def test_live_replay_is_paused_stepped_seeked_and_resumed_over_the_bus(
    zenoh_settings: ZenohSettings, capsys: pytest.CaptureFixture[str]
) -> None:
    prefix = zenoh_settings.prefix
    rec = Recording(SQUARE)
    items = schedule(rec, ["state/joints"], None)
    bus = ["--connect", *zenoh_settings.connect, "--prefix", prefix]
    got: list[bytes] = []
    stop = threading.Event()
    with Node("watch", zenoh_settings) as w, Replayer(zenoh_settings) as replayer:
        w.subscribe_raw(f"{prefix}/state/joints", lambda s, _t: got.append(s.payload.to_bytes()))
        assert replayer.wait_for_subscribers(["state/joints"])
        playback = Playback([i.offset_s for i in items], paused=True, rate=1.0)
        player = threading.Thread(
            target=lambda: replayer.play_controlled(items, playback, stop=stop)
        )
        player.start()
        try:

            def ask(*args: str) -> dict[str, object]:
                code = main(["playback", *args, *bus])
                status: dict[str, object] = json.loads(capsys.readouterr().out)
                assert code == (0 if status["ok"] else 1)
                return status

            eventually(lambda: main(["playback", "status", *bus]) == 0, 10.0, "control answers")
            capsys.readouterr()
            assert ask("step")["ok"]
            eventually(lambda: len(got) == 1, 5.0, "one stepped message")
            assert got[0] == items[0].rec.payload
            status = ask("seek", "15")
            assert status["state"] == "paused" and status["position"] == pytest.approx(15, abs=0.07)
            assert not ask("seek", "999")["ok"]
            ask("rate", "4")
            ask("resume")
            rest = [i for i in items if i.offset_s >= status["position"]]  # type: ignore[operator]
            eventually(lambda: len(got) == 1 + len(rest), 10.0, "the rest at 4x")
            assert got[1:] == [i.rec.payload for i in rest]
        finally:
            stop.set()
            player.join()
