"""``manus pick`` and ``manus place`` against the real services in real time (the live
stack of :mod:`tests.test_sequencer_live`, its simulator holding the shipped cup, bottle
and phone, its camera's frames published as ``manus sim`` does): an unknown object exits
2 with the reason and nothing moves; the cup is picked and placed, on the truth."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import replace

import pytest

from manus.session import ZenohSettings
from schemas.objects import ObjectTruth
from services.simulator.shell import MessagePublisher
from tests.conftest import eventually
from tests.test_sequencer_live import FAST, ROOT, LiveStack

pytestmark = pytest.mark.slow(long=True)


@pytest.fixture
def live(zenoh_settings: ZenohSettings) -> Iterator[LiveStack]:
    stack = LiveStack(zenoh_settings, replace(FAST, objects="default"), planner_process=True)
    stack.sim.on_message = MessagePublisher(stack.node, lambda: stack.sim.wall_t0_ns)
    try:
        eventually(lambda: "cup" in stack.sequencer.core.world.objects, timeout=10.0)
        yield stack
    finally:
        stack.sim.on_message = None  # the node closes first
        stack.close()


def manus(endpoint: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    command = [sys.executable, "-m", "manus_stack.cli", *args]
    return subprocess.run(
        [*command, "--connect", endpoint, "--prefix", "test", "--plain"],
        capture_output=True, text=True, timeout=150, env=env,
    )  # fmt: skip


def test_pick_and_place_the_cup_on_the_real_stack(live: LiveStack, router_endpoint: str) -> None:
    refused = manus(router_endpoint, "pick", "mug")
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "unknown object 'mug' (the world model holds: bottle, cup, phone)" in refused.stderr
    assert not live.results  # nothing moved
    picked = manus(router_endpoint, "pick", "cup")
    assert picked.returncode == 0, picked.stdout + picked.stderr
    assert cup_truth(live).held
    placed = manus(router_endpoint, "place", "cup", "--at", "900", "-330", "790", "0", "0", "0")
    assert placed.returncode == 0, placed.stdout + placed.stderr
    eventually(lambda: cup_truth(live).resting_on == "table", timeout=3.0)
    cup = cup_truth(live)
    assert not cup.held
    assert math.dist(cup.xyz[:2], (0.90, -0.33)) <= 0.010


def cup_truth(live: LiveStack) -> ObjectTruth:
    with live.sim.lock:
        truth = live.sim.core.truth()
    return next(o for o in truth.objects if o.id == "cup")
