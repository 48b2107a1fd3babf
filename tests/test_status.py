"""``manus status``: services alive and where (liveliness), bridge health, arm status."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import threading
from pathlib import Path

from manus.node import Node
from manus.realtime import describe
from manus.session import ZenohSettings
from manus_stack.status import collect, format_status
from schemas import endpoints as ep
from schemas.keys import Keys
from schemas.state import ArmStatus
from tests.test_sequencer_core import bridge_state

ROOT = Path(__file__).resolve().parent.parent


def _arm_status() -> ArmStatus:
    return ArmStatus(stamp_ns=1, seq=1, mode="joint", mode_code=4, msg_class="general",
                     msg_code=9, text="joint mode")  # fmt: skip


def _publish_until(stop: threading.Event, node: Node) -> None:
    bridge = node.publisher(node.keys(ep.BRIDGE_STATE))
    arm = node.publisher(node.keys(ep.STATUS))
    state = bridge_state("running", seq=7, detail="fold_out complete")
    while not stop.wait(0.05):
        bridge.put(state)
        arm.put(_arm_status())


def test_status_shows_services_hosts_bridge_and_arm(zenoh_settings: ZenohSettings) -> None:
    stop = threading.Event()
    with (
        Node("can_bridge", zenoh_settings) as bridge,
        Node("controller", zenoh_settings),
        Node("guardian", zenoh_settings, liveliness=False) as guardian,
        Node("status-test", zenoh_settings, liveliness=False) as viewer,
    ):
        guardian.declare_disabled("single_reader_channel")  # off on purpose
        feeder = threading.Thread(target=_publish_until, args=(stop, bridge), daemon=True)
        feeder.start()
        try:
            status = collect(viewer, wait_s=2.0)
            env = dict(os.environ, MANUS_ZENOH_CONNECT=zenoh_settings.connect[0])
            cli = subprocess.run(
                [sys.executable, "-m", "manus_stack.cli", "status", "--json", "--prefix", "test"],
                capture_output=True,
                text=True,
                timeout=30,
                cwd=ROOT,
                env=env,
            )
        finally:
            stop.set()
            feeder.join(timeout=2.0)
    services = status["services"]
    host = Keys().where("x", socket.gethostname(), 1).split("/")[3]
    here = [{"host": host, "pid": os.getpid()}]
    assert services["can_bridge"] == {"alive": True, "hosts": here, "disabled": None}
    assert services["guardian"] == {
        "alive": False,
        "hosts": [],
        "disabled": "single_reader_channel",
    }
    assert services["controller"]["alive"] and not services["planner"]["alive"]
    assert status["bridge"]["phase"] == "running" and status["bridge"]["cycles"] == 7
    assert status["arm"]["text"] == "joint mode"
    text = format_status(status)
    assert "can_bridge  alive" in text and "planner     DOWN" in text
    assert "guardian    OFF    single_reader_channel: the bridge's CAN channel admits one" in text
    assert "phase running   detail: fold_out complete" in text
    assert "mode joint, general 9: joint mode" in text
    # the command: JSON, exit 1 because the planner and the sequencer are down
    assert cli.returncode == 1, cli.stderr
    shown = json.loads(cli.stdout)
    assert shown["services"]["controller"]["alive"] is True
    assert shown["services"]["sequencer"]["alive"] is False
    assert shown["services"]["guardian"]["disabled"] == "single_reader_channel"


def test_status_without_a_bridge_says_so(zenoh_settings: ZenohSettings) -> None:
    with Node("status-test", zenoh_settings, liveliness=False) as viewer:
        status = collect(viewer, wait_s=0.3)
    assert status["bridge"] is None and status["arm"] is None
    assert not any(info["alive"] for info in status["services"].values())
    text = format_status(status)
    assert "no BridgeState received (is the bridge running?)" in text
    assert "no ArmStatus received" in text


def test_status_shows_each_services_bad_input(zenoh_settings: ZenohSettings) -> None:
    from schemas.state import JointState
    from tests.conftest import eventually

    with (
        Node("controller", zenoh_settings) as controller,
        Node("status-test", zenoh_settings, liveliness=False) as viewer,
    ):
        controller.subscribe(controller.keys(ep.JOINTS), JointState, lambda m, t: None)
        pub = viewer.session.declare_publisher(viewer.keys(ep.JOINTS))
        # The subscription takes a moment to reach the router: publish once it has.
        eventually(lambda: bool(getattr(pub.matching_status, "matching", False)))
        for payload in (b"\xc1", b"not msgpack", b"\x93\x01\x02"):
            pub.put(payload)
        eventually(lambda: sum(controller.bad_payloads.values()) == 3)
        status = collect(viewer, wait_s=0.5)
    assert status["bad_input"]["controller"] == {
        "bad_payloads": 3,
        "by_key": {"state/joints": 3},
        "handler_errors": 0,
        "scheduling": {str(os.getpid()): describe()},  # what the kernel says of this process
    }
    text = format_status(status)
    assert "controller  3 (state/joints 3); 0 handler errors" in text
    assert f"controller  alive  {socket.gethostname()} pid {os.getpid()}  ({describe()})" in text
