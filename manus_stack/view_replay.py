"""``manus replay FILE --view``: a recording shown in Foxglove as the live viewer shows it.

The recording's samples go through the viewer's core (:class:`services.viewer.core.
ViewerCore`) at their recorded pace (``rate``; None: as fast as possible) and out of the
viewer's WebSocket server (:class:`services.viewer.server.FoxgloveSink`), with the
recorded log times. Nothing is published on the bus. Playback waits until a client has
subscribed (open the connection in the app first), then plays ``start_s`` .. ``until_s``
of the recording (seconds from its first message), ``loop`` times over if asked, and
keeps serving until stopped.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from manus.config import load_arm_config
from services.recorder.reading import Recording
from services.viewer.core import ViewerConfig, ViewerCore
from services.viewer.server import DEFAULT_HOST, DEFAULT_PORT, FoxgloveSink


@dataclass
class ViewReplayStats:
    """What a view replay did.

    Attributes:
        samples: recorded samples fed to the core.
        shown: Foxglove messages logged.
        passes: times the selection was played.
    """

    samples: int = 0
    shown: int = 0
    passes: int = 0


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
        probe = ViewerCore(self.config)
        self.sink = FoxgloveSink(
            host=host, port=port, urdf=probe.urdf, describe_topic=probe.topics.robot_description
        )
        self._describe = threading.Event()
        self.sink.on_describe = self._describe.set
        for topic, schema, encoding in probe.channels():
            self.sink.advertise(topic, schema, encoding)
        self.stats = ViewReplayStats()

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

    def play(
        self,
        *,
        rate: float | None = 1.0,
        start_s: float = 0.0,
        until_s: float | None = None,
        loops: int = 1,
        stop: threading.Event | None = None,
    ) -> ViewReplayStats:
        """Play the selection ``loops`` times (a fresh core each time, so paths restart).

        Args:
            rate: time scale (2: twice as fast); None: as fast as possible.
            start_s: start offset from the first message [s].
            until_s: stop at this offset [s] (None: the end).
            loops: how many passes.
            stop: set it to stop early.
        """
        stop = stop or threading.Event()
        first = self.recording.info.start_ns
        lo = first + round(start_s * 1e9)
        hi = None if until_s is None else first + round(until_s * 1e9)
        for _ in range(max(1, loops)):
            core = ViewerCore(self.config)
            self.sink.log(core.robot_description(lo))
            t0_wall = time.monotonic()
            for rec in self.recording.messages():
                if stop.is_set():
                    return self.stats
                if rec.log_ns < lo:
                    continue
                if hi is not None and rec.log_ns > hi:
                    break
                if rate is not None:
                    due = t0_wall + (rec.log_ns - lo) / 1e9 / rate
                    delay = due - time.monotonic()
                    if delay > 0 and stop.wait(delay):
                        return self.stats
                if self._describe.is_set():
                    self._describe.clear()
                    self.sink.log(core.robot_description(rec.log_ns))
                self.stats.samples += 1
                for msg in core.on_sample(rec.key, rec.payload, rec.log_ns):
                    self.sink.log(msg)
                    self.stats.shown += 1
            self.stats.passes += 1
        return self.stats

    def close(self) -> None:
        """Stop the server."""
        self.sink.close()

    def __enter__(self) -> ViewReplay:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
