"""``manus up`` as a separate process: starts every installed service, waits for their
liveliness, stops all of them (and only them) cleanly."""

from __future__ import annotations

import asyncio
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from manus.world_follower import apply_update
from manus_stack.ports import free_port
from schemas import endpoints as ep
from schemas.objects import Perception, WorldObject, WorldUpdate
from services.recorder.reading import Recording
from tests.conftest import eventually
from tests.foxglove_client import collect
from tests.stack_command import stop

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_manus_up_starts_the_stack_and_ctrl_c_stops_it(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    view_port = free_port()
    cmd = [
        sys.executable,
        "-m",
        "manus_stack.cli",
        "up",
        "--endpoint",
        endpoint,
        "--prefix",
        "uptest",
        "--run-dir",
        str(tmp_path),
        "--view",
        "--view-port",
        str(view_port),
    ]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=dict(os.environ),
    )
    try:
        assert proc.stdout is not None
        lines: list[str] = []
        deadline = time.monotonic() + 60.0
        while not any(line.startswith("up: every service is alive") for line in lines):
            assert time.monotonic() < deadline and proc.poll() is None, lines
            lines.append(proc.stdout.readline())
        # the viewer (no liveliness token: it may still be starting) shows the arm moving
        eventually(lambda: _listening(view_port), 30.0, "manus view listening")
        tf = "uptest/viz/tf"
        got = asyncio.run(
            collect(
                f"ws://127.0.0.1:{view_port}",
                [tf],
                until=lambda r: len(r.messages.get(tf, [])) >= 5,
                timeout=30,
            )
        )
        assert len(got.messages.get(tf, [])) >= 5, got.channels.keys()
        os.kill(proc.pid, signal.SIGINT)  # Ctrl-C
        rest, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:  # Ctrl-C first: `manus up` stops its services
            stop(proc)
    out = "".join(lines) + rest
    assert proc.returncode == 0, out + err
    assert f"router: {endpoint} (prefix uptest)" in out
    pids = {}
    for line in out.splitlines():
        words = line.split()
        if len(words) >= 3 and words[1] == "pid":
            pids[words[0]] = int(words[2])
    assert {
        "router", "sim", "bridge", "planner", "controller", "sequencer", "record", "flight", "view"
    } <= set(pids)  # fmt: skip
    down = next(line for line in out.splitlines() if line.startswith("down: "))
    assert all(f"{name} 0" in down for name in pids)  # every child exited cleanly
    for pid in pids.values():
        assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == "zombie"
    logs = {p.stem for p in (tmp_path / "logs").glob("*.log")}
    assert set(pids) <= logs
    text = (tmp_path / "logs" / "sequencer.log").read_text()
    assert "sequencer: serving uptest/sequencer/submit" in text
    assert (tmp_path / "recording.mcap").stat().st_size > 0
    # The simulator's camera reported its objects; the planner's world model kept them.
    recording = Recording(tmp_path / "recording.mcap")
    frames = [m for _, m in recording.decoded([ep.PERCEPTION]) if isinstance(m, Perception)]
    assert {o.id for f in frames for o in f.objects} == {"cup", "bottle", "phone"}
    world = [m for _, m in recording.decoded([ep.OBJECTS]) if isinstance(m, WorldUpdate)]
    assert {o.id for o in follow_updates(world)} == {"cup", "bottle", "phone"}
    assert (tmp_path / "flight").is_dir()
    assert not list((tmp_path / "flight").iterdir())  # an orderly shutdown is no fault


def follow_updates(updates: list[WorldUpdate]) -> list[WorldObject]:
    """The objects a follower of ``updates`` holds at the end (from the first whole set)."""
    held: dict[str, WorldObject] | None = None
    version = 0
    for update in updates:
        if held is None and update.base_version != -1:
            continue  # a follower starting late waits for a whole set
        held = apply_update(held or {}, version, update)
        version = update.version
    return list((held or {}).values())


def _listening(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0
