"""Two computers without Docker: two network namespaces joined by a veth pair.

The ARM namespace runs router (``deploy/zenoh/router-arm.json5``) + simulator + bridge +
controller, the BASE namespace router (``router-base.json5``, which reaches the arm's
router as ``manus-arm``) + planner + sequencer; every service is a client of its own
namespace's router through ``deploy/zenoh/client.json5``. The test creates both
namespaces, the veth pair and a private /30 that exists only inside them (unique names),
and removes them at the end whatever happens. It runs a task, cuts the link mid-path
(``ip link set ... down`` inside the ARM namespace), checks that the arm stops within
two cycles of the last heartbeat and that the sequencer reports the task failed with the
reason, brings the link back, checks that nothing resumes and that a new task runs.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import pytest

from manus.deadman import late_states
from services.sequencer.config import SequencerConfig

ROOT = Path(__file__).resolve().parent.parent
ZENOH = ROOT / "deploy" / "zenoh"
SQUARE = ROOT / "paths" / "thesis_square.txt"
SHORT_TASK = """\
name = "after the link came back"
[[step]]
move = [
  [0, 0, 0,  0, 0, 0,  0, 0, 0,  0, 0, 0,  0.0, 2],
  [0, 30, 0, 0, 0, 0,  0, 0, 0,  0, 0, 0,  2.0, 2],
]
"""

pytestmark = [pytest.mark.netns, pytest.mark.slow]


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10, check=False)


@dataclass
class Net:
    """The two namespaces and the link between them."""

    arm: str
    base: str
    veth_arm: str
    veth_base: str
    addr_arm: str
    addr_base: str
    run_dir: Path
    procs: list[tuple[str, subprocess.Popen[bytes], IO[bytes]]] = field(default_factory=list)

    def spawn(self, ns: str, name: str, argv: list[str], env: dict[str, str]) -> Path:
        log = self.run_dir / f"{name}.log"
        stream = log.open("wb")
        proc = subprocess.Popen(
            ["ip", "netns", "exec", ns, sys.executable, *argv],
            stdout=stream,
            stderr=subprocess.STDOUT,
            env=env,
            cwd=ROOT,
            start_new_session=True,
        )
        self.procs.append((name, proc, stream))
        return log

    def run(self, ns: str, argv: list[str], env: dict[str, str], timeout: float) -> str:
        done = subprocess.run(
            ["ip", "netns", "exec", ns, sys.executable, *argv],
            capture_output=True,
            text=True,
            env=env,
            cwd=ROOT,
            timeout=timeout,
            check=False,
        )
        return done.stdout

    def stop_all(self) -> None:
        for _, proc, _ in reversed(self.procs):
            if proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(proc.pid, signal.SIGINT)
        for _, proc, stream in reversed(self.procs):
            try:
                proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(proc.pid, signal.SIGKILL)
                proc.wait(timeout=5.0)
            stream.close()
        self.procs.clear()

    def dead(self) -> list[str]:
        return [name for name, proc, _ in self.procs if proc.poll() is not None]


SERVICES_DIR = ZENOH / "services"
"""Per-service identities (user names; TLS and access control between the routers),
when the deployment has them: the lab credentials are then made for the test."""


def _env(who: str, prefix: str, lab: Path | None) -> dict[str, str]:
    """Environment of one process: ``who`` is a router file (``router-arm``) or a
    service's Zenoh user (``controller``); with ``lab``, its identity from the lab."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("MANUS_")}
    env.update(MANUS_PREFIX=prefix, PYTHONUNBUFFERED="1")
    if who.startswith("router-"):
        env["MANUS_ZENOH_CONFIG"] = str(ZENOH / f"{who}.json5")
    elif lab is None:
        env["MANUS_ZENOH_CONFIG"] = str(ZENOH / "client.json5")
    else:
        env["MANUS_ZENOH_CONFIG"] = str(SERVICES_DIR / f"{who}.json5")
    if lab is not None:
        env["MANUS_LAB_DIR"] = str(lab)
        for name, var in ((f"{who}.usrpwd", "MANUS_ZENOH_CREDENTIALS"),
                          (f"{who}.password", "MANUS_ZENOH_PASSWORD_FILE")):  # fmt: skip
            if (lab / name).is_file():
                env[var] = str(lab / name)
    return env


def _lab(run_dir: Path) -> Path | None:
    """Fresh lab credentials (``manus certs``) when deploy/zenoh has identities."""
    if not SERVICES_DIR.is_dir():
        return None
    lab = run_dir / "lab"
    importlib.import_module("manus.certs").write_lab(lab)
    return lab


@pytest.fixture
def net(tmp_path: Path) -> Iterator[Net]:
    if sys.platform != "linux" or shutil.which("ip") is None:
        pytest.skip("needs Linux and iproute2 (`ip`) to create network namespaces")
    tag = f"{os.getpid() % 10000:04d}{random.randrange(100):02d}"
    third = random.randrange(256)
    n = Net(
        arm=f"manus-arm-{tag}",
        base=f"manus-base-{tag}",
        veth_arm=f"mva{tag}",
        veth_base=f"mvb{tag}",
        addr_arm=f"10.213.{third}.1",
        addr_base=f"10.213.{third}.2",
        run_dir=tmp_path,
    )
    made = _ip("netns", "add", n.arm)
    if made.returncode != 0:
        pytest.skip(f"cannot create network namespaces here: {made.stderr.strip()}")
    hosts_dir = Path("/etc/netns") / n.base
    try:
        steps = [
            ("netns", "add", n.base),
            ("link", "add", n.veth_arm, "type", "veth", "peer", "name", n.veth_base),
            ("link", "set", n.veth_arm, "netns", n.arm),
            ("link", "set", n.veth_base, "netns", n.base),
            ("-n", n.arm, "addr", "add", f"{n.addr_arm}/30", "dev", n.veth_arm),
            ("-n", n.base, "addr", "add", f"{n.addr_base}/30", "dev", n.veth_base),
            ("-n", n.arm, "link", "set", "lo", "up"),
            ("-n", n.base, "link", "set", "lo", "up"),
            ("-n", n.arm, "link", "set", n.veth_arm, "up"),
            ("-n", n.base, "link", "set", n.veth_base, "up"),
        ]
        for step in steps:
            done = _ip(*step)
            assert done.returncode == 0, f"ip {' '.join(step)}: {done.stderr}"
        # compose.yaml's extra_hosts: the base router reaches the arm's as manus-arm
        hosts_dir.mkdir(parents=True, exist_ok=True)
        (hosts_dir / "hosts").write_text(f"127.0.0.1 localhost\n{n.addr_arm} manus-arm\n")
        yield n
    finally:
        n.stop_all()
        _ip("netns", "del", n.arm)
        _ip("netns", "del", n.base)  # the veth pair goes with its namespaces
        shutil.rmtree(hosts_dir, ignore_errors=True)


def _status(net: Net, ns: str, env: dict[str, str]) -> dict[str, Any]:
    out = net.run(ns, ["-m", "manus_stack.cli", "status", "--json", "--wait", "1"], env, 30.0)
    return dict(json.loads(out)) if out.strip() else {}


def _wait_status(net: Net, ns: str, env: dict[str, str], alive: set[str], timeout: float) -> None:
    end = time.monotonic() + timeout
    status: dict[str, Any] = {}
    while time.monotonic() < end:
        assert not net.dead(), f"exited: {net.dead()} (logs in {net.run_dir})"
        status = _status(net, ns, env)
        services = status.get("services", {})
        up = {n for n, info in services.items() if info["alive"]}
        bridge = status.get("bridge") or {}
        if alive <= up and bridge.get("phase") == "running":
            return
        time.sleep(0.5)
    raise AssertionError(f"{ns}: not all of {sorted(alive)} alive and running: {status}")


def _tx(probe: Path, since_ns: int) -> list[tuple[int, int, bool]]:
    rows = []
    for line in probe.read_text().splitlines():
        parts = line.split()
        if len(parts) == 3 and int(parts[0]) >= since_ns:
            rows.append((int(parts[0]), int(parts[1]), parts[2] == "1"))
    return rows


def _moves(probe: Path, since_ns: int) -> list[tuple[int, bool]]:
    return [(t, zero) for t, fid, zero in _tx(probe, since_ns) if fid == 0x374]


EVERYTHING = {"can_bridge", "controller", "planner", "sequencer"}


def _start_stack(net: Net, env: Callable[[str], dict[str, str]], probe: Path) -> None:
    """The two computers' processes, each with its own credentials; ``probe`` records the
    frames the bridge sends."""
    net.run_dir.joinpath("sim.json").write_text(json.dumps({"start_pose": "unfolded"}))
    device = net.run_dir / "sim.device"
    cli = ["-m", "manus_stack.cli"]

    # ---- the arm computer
    net.spawn(net.arm, "router-arm", ["-m", "tests.netns_helper", "router"],
              env("router-arm"))  # fmt: skip
    time.sleep(1.0)
    net.spawn(net.arm, "sim", [*cli, "sim", "--device-file", str(device), "--config",
                               str(net.run_dir / "sim.json")], env("simulator"))  # fmt: skip
    net.spawn(net.arm, "bridge", [*cli, "bridge", "--device-file", str(device),
                                  "--wait-device", "20"], env("can_bridge"))  # fmt: skip
    net.spawn(net.arm, "controller", [*cli, "controller"], env("controller"))
    probe.touch()
    net.spawn(
        net.arm, "probe", ["-m", "tests.netns_helper", "probe", str(probe)], env("controller")
    )
    # ---- the base computer
    net.spawn(net.base, "router-base", ["-m", "tests.netns_helper", "router"],
              env("router-base"))  # fmt: skip
    net.spawn(net.base, "planner", [*cli, "planner"], env("planner"))
    net.spawn(net.base, "sequencer", [*cli, "sequencer"], env("sequencer"))


def _run_and_cut(net: Net, base_env: dict[str, str], probe: Path, run_log: Path) -> tuple[int, int]:
    """``manus run`` the square on the base computer; once the arm has moved for 1.5 s, cut
    the arm computer's link. Returns the run's exit status and the time of the cut [ns]."""
    cli = ["-m", "manus_stack.cli"]
    with run_log.open("wb") as out:
        run = subprocess.Popen(
            ["ip", "netns", "exec", net.base, sys.executable, *cli, "run", "--plain",
             str(SQUARE)],
            stdout=out, stderr=subprocess.STDOUT, env=base_env, cwd=ROOT, start_new_session=True,
        )  # fmt: skip
        try:
            end = time.monotonic() + 20.0
            while True:
                moving = [t for t, zero in _moves(probe, 0) if not zero]
                if moving and moving[-1] - moving[0] > 1_500_000_000:
                    break
                assert time.monotonic() < end and run.poll() is None, run_log.read_text()
                time.sleep(0.05)
            cut = time.time_ns()
            done = _ip("-n", net.arm, "link", "set", net.veth_arm, "down")
            assert done.returncode == 0, done.stderr
            return run.wait(timeout=15.0), cut
        finally:
            if run.poll() is None:
                os.kill(run.pid, signal.SIGKILL)
                run.wait()


def test_cut_link_between_the_computers(net: Net) -> None:
    t0 = time.monotonic()
    lab = _lab(net.run_dir)

    def env(who: str) -> dict[str, str]:
        return _env(who, "netns", lab)

    base_env = env("supervisor")  # manus status, manus run
    cli = ["-m", "manus_stack.cli"]
    probe = net.run_dir / "probe.txt"
    _start_stack(net, env, probe)
    _wait_status(net, net.base, base_env, EVERYTHING, 40.0)
    up_s = time.monotonic() - t0

    # ---- a task, cut mid-path
    run_log = net.run_dir / "run1.log"
    code, cut = _run_and_cut(net, base_env, probe, run_log)
    time.sleep(1.0)
    moves = _moves(probe, cut)
    first_zero = next(t for t, zero in moves if zero)
    stop_ms = (first_zero - cut) / 1e6
    assert all(zero for t, zero in moves if t >= first_zero), "moved again after stopping"
    text = run_log.read_text()
    assert code == 1, text
    # the sequencer notices the silence (link_timeout_s 0.5 s) before the link's lease
    # (1 s, as deployed) takes the arm's liveliness tokens; either names the loss
    assert "task failed" in text, text
    assert "no joint states from the arm" in text or "is gone (its liveliness" in text, text

    # ---- the link returns: nothing resumes, a new task runs normally
    done = _ip("-n", net.arm, "link", "set", net.veth_arm, "up")
    assert done.returncode == 0, done.stderr
    back = time.time_ns()
    _wait_status(net, net.base, base_env, EVERYTHING, 30.0)
    reconnect_s = (time.time_ns() - back) / 1e9
    assert all(zero for _, zero in _moves(probe, back)), "resumed by itself"
    task = net.run_dir / "short.toml"
    task.write_text(SHORT_TASK)
    second = subprocess.run(
        ["ip", "netns", "exec", net.base, sys.executable, *cli, "run", "--plain", str(task)],
        capture_output=True, text=True, env=base_env, cwd=ROOT, timeout=40,
    )  # fmt: skip
    assert second.returncode == 0, second.stdout + second.stderr
    assert any(not zero for _, zero in _moves(probe, back)), "the new task moved the arm"
    print(
        f"NETNS link cut: first zero 0x374 {stop_ms:.0f} ms after the cut; stack up in "
        f"{up_s:.1f} s, link back in {reconnect_s:.1f} s, total {time.monotonic() - t0:.1f} s"
    )
    print("NETNS sequencer:", [ln for ln in text.splitlines() if "task failed" in ln][-1])
    # the states the deadman lets pass, the one answered with zeros, the reply delay, and a
    # margin for load
    cycles = late_states(SequencerConfig().heartbeat_timeout_s, 60_000_000) + 1
    assert stop_ms <= cycles * 60 + 20 + 60, stop_ms
