"""``manus pick`` and ``manus place`` against the stack's real processes in real time
(``manus up``'s, through :class:`tests.fault_stack.FaultStack`: the simulator holding the
shipped cup, bottle and phone, its camera reporting them): an unknown object exits 2
with the reason and nothing moves; the cup is picked and placed, on the truth, touching
nothing on the way.

The stack used to run in the test's own process (the simulator and the bridge on its
threads, as :mod:`tests.test_sequencer_live` does): on a loaded machine, whatever else that
process did held the bridge's thread back, and the arm stopped on its own deadmen
("joint states interrupted: 360 ms apart", a resync at the retreat)."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from manus_stack.ports import free_port
from schemas.objects import ObjectTruth
from schemas.state import SimTruth
from tests.fault_stack import FaultStack
from tests.test_sequencer_live import ROOT

pytestmark = pytest.mark.slow(long=True)

WORLD_S = 20.0
"""How long the sequencer may take to learn the camera's objects after the start [s]."""


@pytest.fixture
def live(tmp_path: Path) -> Iterator[FaultStack]:
    with FaultStack(tmp_path / "run", f"tcp/127.0.0.1:{free_port()}", "pick") as stack:
        stack.start()
        yield stack


def manus(stack: FaultStack, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    command = [sys.executable, "-m", "manus_stack.cli", *args]
    options = stack.options
    return subprocess.run(
        [*command, "--connect", options.endpoint, "--prefix", options.prefix, "--plain"],
        capture_output=True, text=True, timeout=150, env=env,
    )  # fmt: skip


def test_pick_and_place_the_cup_on_the_real_stack(live: FaultStack) -> None:
    known = "unknown object 'mug' (the world model holds: bottle, cup, phone)"
    deadline = time.monotonic() + WORLD_S
    while True:  # a refusal moves nothing: asked again until the world model is whole
        start_ns = time.time_ns()
        refused = manus(live, "pick", "mug")
        if known in refused.stderr or time.monotonic() > deadline:
            break
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert known in refused.stderr
    moves = live.watch.joint_moves(start_ns)  # the bridge's 0x374 frames meanwhile
    assert moves and all(zero for _, zero in moves), "the arm was told to move"
    picked = manus(live, "pick", "cup")
    assert picked.returncode == 0, picked.stdout + picked.stderr
    assert cup(latest(live)).held
    placed = manus(live, "place", "cup", "--at", "900", "-330", "790", "0", "0", "0")
    assert placed.returncode == 0, placed.stdout + placed.stderr
    live.wait("the cup resting on the table", lambda: cup(latest(live)).resting_on == "table", 3.0)
    truth = latest(live)
    assert not cup(truth).held
    assert math.dist(cup(truth).xyz[:2], (0.90, -0.33)) <= 0.010
    assert truth.contacts == 0 and not truth.object_contacts, (
        truth.contact, truth.object_contacts,
    )  # fmt: skip


def latest(stack: FaultStack) -> SimTruth:
    return stack.watch.truths()[-1]


def cup(truth: SimTruth) -> ObjectTruth:
    return next(o for o in truth.objects if o.id == "cup")
