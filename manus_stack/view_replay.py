"""``manus replay FILE --view``: a recording shown in Foxglove as the live viewer shows it.

The recording's samples go through the viewer's core (:class:`services.viewer.core.
ViewerCore`) and out of the viewer's WebSocket server (:class:`services.viewer.server.
FoxgloveSink`), with the recorded log times, paced by the replay's clock
(:class:`services.recorder.playback.Playback`: ``rate``, ``start_s`` .. ``until_s``,
``loops``). Nothing is published on the bus. Playback waits until a client has subscribed
(open the connection in the app first).

The server announces the recording's time range, so the app shows its playback bar: play,
pause, speed and seek requests go to the same clock (a seek starts the view afresh from
there: a new core, the executed path from that point on, the scene as the last scene
state before that point left it), and the server tells the app the current time as it
plays.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from foxglove.websocket import (
    PlaybackCommand,
    PlaybackControlRequest,
    PlaybackState,
    PlaybackStatus,
)

from manus.config import load_arm_config
from schemas.endpoints import SCENE_STATE
from schemas.playback import PlaybackControl
from services.recorder.playback import Playback
from services.recorder.reading import Recorded, Recording
from services.viewer.config import ViewerConfig
from services.viewer.core import ViewerCore
from services.viewer.server import DEFAULT_HOST, DEFAULT_PORT, FoxgloveSink

TIME_EVERY_NS = 50_000_000
"""Tell the app the playback time at least this often [ns of log time]."""
_STATUS = {
    "playing": PlaybackStatus.Playing,
    "paused": PlaybackStatus.Paused,
    "finished": PlaybackStatus.Ended,
}


@dataclass
class ViewReplayStats:
    """What a view replay did.

    Attributes:
        samples: recorded samples fed to the core.
        shown: Foxglove messages logged.
        passes: times the selection was played.
        app_requests: playback requests from the app (play, pause, speed, seek).
    """

    samples: int = 0
    shown: int = 0
    passes: int = 0
    app_requests: int = 0


class ViewReplay:
    """Serves a recording to Foxglove (see the module docstring).

    Args:
        path: the MCAP recording.
        host: WebSocket address (loopback by default).
        port: WebSocket port (0: any free one).
    """

    def __init__(self, path: str, *, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT) -> None:
        self.recording = Recording(path)
        self.prefix = self.recording.info.prefix or "manus"
        self.config = ViewerConfig(prefix=self.prefix, arm=load_arm_config())
        self.records: list[Recorded] = list(self.recording.messages())
        self.first_ns = self.records[0].log_ns if self.records else 0
        self._scene_states = [i for i, r in enumerate(self.records) if r.suffix == SCENE_STATE]
        probe = ViewerCore(self.config)
        self.sink = FoxgloveSink(
            host=host,
            port=port,
            urdf=probe.urdf,
            describe_topics=(probe.topics.robot_description, probe.topics.scene),
            playback_range=(self.first_ns, self.records[-1].log_ns if self.records else 0),
        )
        self._describe = threading.Event()
        self.sink.on_describe = self._describe.set
        self.sink.on_playback = self._on_app_request
        for topic, schema, encoding in probe.channels():
            self.sink.advertise(topic, schema, encoding)
        self.stats = ViewReplayStats()
        self.playback: Playback | None = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._fresh = False  # a seek: start the view afresh

    @property
    def port(self) -> int:
        """The WebSocket port."""
        return self.sink.port

    def wait_for_client(self, stop: threading.Event, timeout: float | None = None) -> bool:
        """Wait until a client has subscribed to something (True), or stop/timeout."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.sink.client_events["subscribe"]:
            if stop.is_set() or (deadline is not None and time.monotonic() > deadline):
                return False
            stop.wait(0.05)
        return True

    def _state(self, request_id: str | None, did_seek: bool) -> PlaybackState:
        p = self.playback
        assert p is not None
        status = p.status()
        return PlaybackState(
            status=_STATUS[status.state],
            current_time=self.first_ns + round(status.position * 1e9),
            playback_speed=status.rate or 1.0,
            did_seek=did_seek,
            request_id=request_id,
        )

    def _on_app_request(self, req: PlaybackControlRequest) -> PlaybackState | None:
        """The app's play, pause, speed and seek (on an SDK thread)."""
        with self._lock:
            p = self.playback
            if p is None:  # not playing yet
                return None
            self.stats.app_requests += 1
            now = time.monotonic()
            did_seek = False
            if req.seek_time is not None:
                offset = (req.seek_time - self.first_ns) / 1e9
                lo, hi = p.offsets[p.first], p.offsets[p.end - 1]
                did_seek = p.control(
                    PlaybackControl(action="seek", value=min(max(offset, lo), hi)), now
                ).ok
                self._fresh = self._fresh or did_seek
            if req.playback_speed > 0 and p.rate is not None:
                p.control(PlaybackControl(action="rate", value=req.playback_speed), now)
            action = "resume" if req.playback_command == PlaybackCommand.Play else "pause"
            p.control(PlaybackControl(action=action), now)
            state = self._state(req.request_id, did_seek)
        self._wake.set()
        return state

    def play(
        self,
        *,
        rate: float | None = 1.0,
        start_s: float = 0.0,
        until_s: float | None = None,
        loops: int = 1,
        paused: bool = False,
        stop: threading.Event | None = None,
    ) -> ViewReplayStats:
        """Play the selection ``loops`` times (a fresh core each pass and after a seek, so
        the paths restart), as the app's playback bar asks meanwhile.

        Args:
            rate: time scale (2: twice as fast); None: as fast as possible.
            start_s: start offset from the first message [s].
            until_s: stop after this offset [s] (None: the end).
            loops: how many passes.
            paused: start paused (the app's play button starts it).
            stop: set it to stop early.
        """
        stop = stop or threading.Event()
        offsets = [(r.log_ns - self.first_ns) / 1e9 for r in self.records]
        with self._lock:
            self.playback = p = Playback(
                offsets, rate=rate, start_s=start_s, until_s=until_s, loops=loops, paused=paused
            )
        core: ViewerCore | None = None
        loop = 0
        told_ns = -TIME_EVERY_NS
        while not stop.is_set():
            with self._lock:
                now = time.monotonic()
                due = p.due(now)
                if p.state == "finished":
                    break
                index = p.take(now) if due is not None and due <= now else -1
                fresh, self._fresh = self._fresh, False
                if p.loop != loop:
                    loop, fresh = p.loop, True
            if index < 0:
                self._wake.wait(0.1 if due is None else min(due - now, 0.1))
                self._wake.clear()
                continue
            rec = self.records[index]
            if core is None or fresh:
                core = self._fresh_core(index)
                self._describe.set()
            if self._describe.is_set():
                self._describe.clear()
                for msg in core.describe(rec.log_ns):
                    self.sink.log(msg)
            self.stats.samples += 1
            for msg in core.on_sample(rec.key, rec.payload, rec.log_ns):
                self.sink.log(msg)
                self.stats.shown += 1
            if abs(rec.log_ns - told_ns) >= TIME_EVERY_NS:
                self.sink.server.broadcast_time(rec.log_ns)
                told_ns = rec.log_ns
        self.stats.passes = p.loop if p.state == "finished" else p.loop - 1
        with self._lock:
            self.sink.server.broadcast_playback_state(self._state(None, False))
        return self.stats

    def _fresh_core(self, index: int) -> ViewerCore:
        """A new core that knows the scene in use at record ``index`` (the scene states
        recorded before it), so a seek past a scene change still draws the new scene."""
        core = ViewerCore(self.config)
        for i in self._scene_states:
            if i >= index:
                break
            rec = self.records[i]
            core.on_sample(rec.key, rec.payload, rec.log_ns)
        return core

    def close(self) -> None:
        """Stop the server."""
        self.sink.close()

    def __enter__(self) -> ViewReplay:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
