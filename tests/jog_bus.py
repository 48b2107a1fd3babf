"""A lock-step arm whose jog endpoints are on a real Zenoh router (a test rig).

The simulator, bridge and controller cores run on the lock-step clock
(:class:`~manus_stack.jog_lockstep.JogArm`); the rig carries the controller's jog
endpoints over Zenoh, as raw MessagePack payloads, so that a client written from the
published JSON Schema alone (plain ``zenoh`` and ``msgpack``) can drive it:

- ``<prefix>/jog``: every payload a client publishes is queued and handed to the
  controller at :meth:`JogBus.advance` (one that does not decode goes to its input's bad
  handler, as the live shell does);
- ``<prefix>/controller/jog_level``: answered by the controller (under the rig's lock);
- ``<prefix>/controller/jog_state``: every JogState the controller published while the
  rig advanced, put on the bus as it was encoded.

Simulated time moves only in :meth:`JogBus.advance`, so the client's commands and the
states it reads are in lock-step with the arm: the test is fast and deterministic.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Any

import numpy as np
import zenoh

from manus.config import DEFAULT_ARM
from manus.errors import SchemaError
from manus.kinematics import fk_position
from manus.scene import default_scene
from manus.session import ZenohSettings, open_session
from manus.wiring import BAD_PAYLOAD
from manus_stack.jog_lockstep import JogArm
from schemas import endpoints as ep
from schemas.base import Message
from schemas.jog import JogCommand, JogLevel
from services.controller.wiring import WIRING
from services.simulator.config import SimConfig


class JogBus:
    """The rig (see the module docstring).

    Args:
        settings: the test's Zenoh settings (router and prefix).
    """

    def __init__(self, settings: ZenohSettings) -> None:
        self.arm = JogArm(SimConfig(start_pose="unfolded"))
        self.arm.start()
        self.lock = threading.Lock()
        self.session = open_session(settings)
        self._keys = settings.prefix
        self._inbox: queue.Queue[bytes] = queue.Queue()
        self._published = len(self.arm.states())
        key = f"{self._keys}/{ep.JOG}"
        self._sub = self.session.declare_subscriber(key, self._on_jog)
        self._pub = self.session.declare_publisher(f"{self._keys}/{ep.JOG_STATE}")
        level = f"{self._keys}/{ep.JOG_LEVEL}"
        self._level = self.session.declare_queryable(level, self._on_level)

    @property
    def toward_head(self) -> list[float]:
        """The unit vector from the gripper to the centre of the shipped scene's head, in
        the arm's base frame (what the test asks the client to push)."""
        scene = default_scene()
        head = next(o for o in scene.objects if o.name == "head")
        centre = (np.linalg.inv(scene.mount) @ head.body.pose)[:3, 3]
        js = self.arm.core.last_js
        assert js is not None
        gripper = fk_position(np.asarray(js.position), DEFAULT_ARM)
        way = centre - gripper
        return [float(v) for v in way / np.linalg.norm(way)]

    def advance(self, seconds: float, expect: int = 1, timeout: float = 5.0) -> int:
        """Take the ``expect`` payloads the client published (waiting for them at most
        ``timeout`` s of wall time), run ``seconds`` of simulated time, and put the
        JogStates of that time on the bus. Returns how many were put."""
        taken: list[bytes] = []
        deadline = time.monotonic() + timeout
        while len(taken) < expect:
            left = deadline - time.monotonic()
            assert left > 0, f"only {len(taken)} of {expect} jog payloads arrived"
            try:
                taken.append(self._inbox.get(timeout=left))
            except queue.Empty:
                continue
        with self.lock:
            for payload in taken:
                self._feed(payload)
            self.arm.run(seconds)
            states = self.arm.states()[self._published :]
            self._published += len(states)
        for state in states:
            self._pub.put(state.encode())
        return len(states)

    def close(self) -> None:
        """Leave the bus."""
        self.session.close()  # its subscriber, publisher and queryable with it

    # -- plumbing ---------------------------------------------------------------------------

    def _on_jog(self, sample: zenoh.Sample) -> None:
        self._inbox.put(sample.payload.to_bytes())

    def _feed(self, payload: bytes) -> None:
        try:
            cmd: Message = JogCommand.decode(payload)
        except SchemaError:  # as the node counts it: the input's bad handler
            outputs = WIRING.feed_bad(self.arm.core, ep.JOG, BAD_PAYLOAD, self.arm.ls.t_ns)
        else:
            self.arm.ls.publish(ep.JOG, cmd)
            return
        for suffix, msg in outputs:
            self.arm.ls.publish(suffix, msg)

    def _on_level(self, query: zenoh.Query) -> None:
        payload = query.payload
        request = JogLevel.decode(payload.to_bytes() if payload is not None else b"")
        with self.lock:
            reply: Any = self.arm.query(ep.JOG_LEVEL, request)
        query.reply(query.key_expr, reply.encode())
