"""``manus up`` as a separate process: starts every installed service, waits for their
liveliness, stops all of them (and only them) cleanly."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import psutil
import pytest

from tests.conftest import free_port

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_manus_up_starts_and_stops_the_stack(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cmd = [sys.executable, "-m", "manus_stack.cli", "up", "--endpoint", endpoint,
           "--prefix", "uptest", "--run-dir", str(tmp_path), "--duration", "1"]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, cwd=ROOT,
                          env=dict(os.environ))  # fmt: skip
    out = proc.stdout
    assert proc.returncode == 0, out + proc.stderr
    assert f"router: {endpoint} (prefix uptest)" in out
    assert "up: every service is alive" in out
    pids = {}
    for line in out.splitlines():
        words = line.split()
        if len(words) >= 3 and words[1] == "pid":
            pids[words[0]] = int(words[2])
    assert {"router", "sim", "planner", "controller", "sequencer"} <= set(pids)
    down = next(line for line in out.splitlines() if line.startswith("down: "))
    assert all(f"{name} 0" in down for name in pids)  # every child exited cleanly
    for pid in pids.values():
        assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == "zombie"
    logs = {p.stem for p in (tmp_path / "logs").glob("*.log")}
    assert set(pids) <= logs
    assert (
        "sequencer: serving uptest/sequencer/submit"
        in (tmp_path / "logs" / "sequencer.log").read_text()
    )
