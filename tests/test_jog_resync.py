"""A jog held through a bridge resync (found beside two CPU hogs: the in-process test
stack's bridge resynced, the controller refused the jog's next command and latched a stop,
and the user had to release the key to jog again). A resync is a few cycles of zeros that
the bridge ends by itself: the jog waits it out; a longer outage still stops it."""

from __future__ import annotations

import dataclasses

from schemas import endpoints as ep
from schemas.control import EndCause
from schemas.jog import JogCommand
from schemas.state import BridgeState
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore
from services.controller.jog import JogSource
from tests.controller_plant import Plant, feed, steps

RUNNING = BridgeState(
    stamp_ns=0, seq=0, phase="running", estop=False, cycles=10, period_ms=60.0,
    jitter_ms=0.0, reply_latency_ms=1.0, reply_latency_max_ms=1.0, missed_windows=0,
    stale_commands=0, resyncs=0, dropped_frames=0, duplicate_frames=0, garbled_frames=0,
    buffered_syncs=0, bad_payloads=0, detail="",
)  # fmt: skip


class Jogger:
    """A user holding a key: one moving command per cycle."""

    def __init__(self, plant: Plant) -> None:
        self.plant, self.seq = plant, 0

    def send(self, linear: float = 0.08) -> None:
        self.seq += 1
        cmd = JogCommand(
            stamp_ns=0, seq=self.seq, source="test", kind="twist", units="si",
            linear=[linear, 0.0, 0.0],
        )  # fmt: skip
        feed(self.plant.core, ep.JOG, cmd)

    def cycles(self, n: int, *, skip: bool = False) -> None:
        for _ in range(n):
            self.send()
            self.plant.cycle(skip=skip)


def bridge(plant: Plant, phase: str) -> None:
    plant.collect(plant.core.on_bridge_state(dataclasses.replace(RUNNING, phase=phase)))


def moved(plant: Plant, n: int) -> bool:
    """Whether any of the last ``n`` commands moves a motor."""
    return any(any(steps(c)[1:7]) for c in plant.commands[-n:])


def start() -> tuple[Plant, Jogger, JogSource]:
    plant = Plant(ControllerCore(ControllerConfig()))
    bridge(plant, "running")
    plant.run(3)
    user = Jogger(plant)
    user.cycles(6)
    assert moved(plant, 3)
    return plant, user, plant.core.source(JogSource)


def test_a_held_jog_goes_on_after_a_resync_without_a_release() -> None:
    plant, user, jog = start()
    bridge(plant, "resync")
    user.cycles(3, skip=True)  # faulty cycles, no joint states: the commands come in the gap
    assert jog.stopped is None and jog.refused == 0 and jog.engaged
    user.cycles(1)  # a clean cycle of the resync (its joint state; the bridge sends zeros)
    assert steps(plant.commands[-1])[1:7] == [0] * 6  # the gap: zeros, start afresh
    user.cycles(1)
    bridge(plant, "running")  # after two clean cycles
    user.cycles(4)
    assert moved(plant, 3) and jog.stopped is None and jog.refused == 0


def test_a_jog_started_during_a_resync_waits_for_the_next_joint_state() -> None:
    plant = Plant(ControllerCore(ControllerConfig()))
    bridge(plant, "running")
    plant.run(3)
    jog = plant.core.source(JogSource)
    user = Jogger(plant)
    bridge(plant, "resync")
    plant.cycle(skip=True)
    user.send()
    plant.cycle(skip=True)
    assert jog.engaged and jog.refused == 0
    user.cycles(2)
    bridge(plant, "running")
    user.cycles(4)
    assert moved(plant, 3) and jog.stopped is None


def test_a_resync_longer_than_the_outage_limit_stops_the_jog_until_a_release() -> None:
    plant, user, jog = start()
    bridge(plant, "resync")
    user.cycles(6, skip=True)  # 360 ms without states: more than max_outage_ms
    user.cycles(2)
    bridge(plant, "running")
    user.cycles(3)
    assert jog.stopped is not None and jog.stopped.cause == EndCause.STATES_INTERRUPTED
    assert not moved(plant, 3) and "release the controls" in jog.reason
    user.send(0.0)  # released
    user.cycles(4)
    assert moved(plant, 3)


def test_other_phases_still_refuse_and_latch() -> None:
    plant, user, jog = start()
    bridge(plant, "stopped")
    assert jog.stopped is not None and jog.stopped.cause == EndCause.BRIDGE_PHASE
    bridge(plant, "running")
    user.cycles(3)
    assert not moved(plant, 3) and jog.stopped is not None
