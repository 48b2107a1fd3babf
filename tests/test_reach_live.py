"""``manus move-to`` and ``manus reach`` against the real services in real time (the
live stack of :mod:`tests.test_sequencer_live`): a goal runs through the sequencer, a
refused one exits 2 with the reason and nothing moves."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.kinematics import fk
from manus.named_poses import named_poses
from manus.session import ZenohSettings
from tests.conftest import eventually
from tests.test_sequencer_live import ROOT, LiveStack

pytestmark = pytest.mark.slow


@pytest.fixture
def live(zenoh_settings: ZenohSettings) -> Iterator[LiveStack]:
    stack = LiveStack(zenoh_settings)
    try:
        yield stack
    finally:
        stack.close()


def manus(endpoint: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    command = [sys.executable, "-m", "manus_stack.cli", *args]
    return subprocess.run(
        [*command, "--connect", endpoint, "--prefix", "test", "--plain"],
        capture_output=True, text=True, timeout=90, env=env,
    )  # fmt: skip


def test_move_to_and_a_refused_reach_on_the_real_stack(
    live: LiveStack, router_endpoint: str
) -> None:
    refused = manus(router_endpoint, "reach", "--to-pose", "600", "100", "-240", "0", "180", "0")
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "planner refused (goal_collision)" in refused.stderr and "table" in refused.stderr
    assert not live.results  # nothing moved
    done = manus(router_endpoint, "move-to", "drink")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "task" in done.stdout and done.stdout.strip().endswith("succeeded")
    eventually(lambda: len(live.results) >= 1, timeout=3.0)
    assert [r.status for r in live.results] == ["succeeded"]
    drink = np.array(named_poses("")["drink"].joints)
    reached = fk(np.array(live.joints[-1][1].position), DEFAULT_ARM)[:3, 3]
    assert np.linalg.norm(reached - fk(drink, DEFAULT_ARM)[:3, 3]) < 0.005
