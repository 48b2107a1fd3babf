"""A service forked from the warm forkserver (manus_stack/forks.py) runs as its command
would from a fresh interpreter: its output in its log, its exit status or the signal that
ended it, its working directory; and it is not forked where the forkserver's imports
would differ from what a fresh interpreter would read."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from manus_stack import forks
from manus_stack.forks import Forked, forkable
from manus_stack.ports import free_port, port_in_use
from manus_stack.up import LocalStack, StackOptions

ROOT = Path(__file__).resolve().parent.parent
FK = [sys.executable, "-m", "manus_stack.cli", "kin", "fk", "0", "0", "0", "0", "0", "0"]


@pytest.mark.slow
def test_a_fork_writes_what_its_command_prints_and_exits_as_it(tmp_path: Path) -> None:
    fresh = subprocess.run(FK, capture_output=True, text=True, check=True, cwd=ROOT)
    log = tmp_path / "fk.log"
    child = Forked(FK, dict(os.environ), log, 0)
    assert child.wait(timeout=30.0) == 0
    assert log.read_text() == fresh.stdout
    bad = Forked([*FK[:-1]], dict(os.environ), tmp_path / "bad.log", 0)  # one angle short
    assert bad.wait(timeout=30.0) == 2  # argparse's usage error
    assert "the following arguments are required" in (tmp_path / "bad.log").read_text()


@pytest.mark.slow
def test_a_fork_takes_its_working_directory_and_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The working directory is the launcher's when it starts the service (not when the
    forkserver started), the environment the one given: a relative ``$MANUS_SCENE``
    resolves there."""
    Forked(FK, dict(os.environ), tmp_path / "first.log", 0).wait(timeout=30.0)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.yaml").write_text("[scene\n")
    child = Forked(
        [sys.executable, "-m", "manus_stack.cli", "scene", "check"],
        {**os.environ, "MANUS_SCENE": "bad.yaml"},
        tmp_path / "scene.log",
        0,
    )
    assert child.wait(timeout=30.0) == 1  # a bad input file
    text = (tmp_path / "scene.log").read_text()
    assert "bad.yaml:2: not valid YAML" in text, text  # the given $MANUS_SCENE, found here


@pytest.mark.slow
def test_a_killed_fork_reports_the_signal(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    argv = [sys.executable, "-m", "manus_stack.cli", "router", "--listen", endpoint]
    child = Forked(argv, dict(os.environ), tmp_path / "router.log", 0)
    deadline = time.monotonic() + 30.0
    while not port_in_use(endpoint):
        assert child.poll() is None, (tmp_path / "router.log").read_text()
        assert time.monotonic() < deadline, "the forked router did not listen"
        time.sleep(0.05)
    with pytest.raises(subprocess.TimeoutExpired):
        child.wait(timeout=0.1)
    assert os.getsid(child.pid) == child.pid  # a session of its own, as manus up's
    os.kill(child.pid, signal.SIGKILL)
    assert child.wait(timeout=10.0) == -signal.SIGKILL
    assert child.returncode == -signal.SIGKILL


def test_another_import_time_environment_starts_a_fresh_interpreter(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """NumPy reads its dispatch at import: a service asked for with another one is not
    forked from a forkserver that imported NumPy with this process's."""
    monkeypatch.setattr(forks, "_context", object())  # as once the forkserver started
    monkeypatch.setattr(forks, "_import_env", {})
    assert forkable({"PATH": "/bin", "MANUS_PREFIX": "other"})
    assert not forkable({"NPY_DISABLE_CPU_FEATURES": "AVX512F"})
    assert not forkable({"NUMBA_CACHE_DIR": "/elsewhere"})
    assert not forkable({"MANUS_FORK": "0"})
    monkeypatch.setenv("MANUS_FORK", "0")
    assert not forkable({})


@pytest.mark.slow
def test_a_launching_script_without_a_main_guard_runs_once(tmp_path: Path) -> None:
    """The forkserver would run the launcher's main module again in the child; a script
    that starts a service at its top level (no ``if __name__ == "__main__"``) must not
    start another from each child."""
    script = tmp_path / "launch.py"
    script.write_text(
        "import os, sys\n"
        "from pathlib import Path\n"
        "from manus_stack.forks import Forked\n"
        f"argv = {FK!r}\n"
        "log = Path(sys.argv[1]) / f'fk-{os.getpid()}.log'\n"
        "print('launched', flush=True)\n"
        "sys.exit(Forked(argv, dict(os.environ), log, 0).wait(timeout=60.0))\n"
    )
    done = subprocess.run(
        [sys.executable, str(script), str(tmp_path)],
        capture_output=True, text=True, timeout=120.0, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("launched") == 1
    assert len(list(tmp_path.glob("fk-*.log"))) == 1


@pytest.mark.slow
def test_with_forks_off_the_stack_starts_fresh_interpreters(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``MANUS_FORK=0``: every service a child of the launcher, started afresh; the stack
    still comes up, runs and stops cleanly."""
    monkeypatch.setenv("MANUS_FORK", "0")
    options = StackOptions(
        run_dir=tmp_path / "run", endpoint=f"tcp/127.0.0.1:{free_port()}", prefix="fresh",
        record=False, guardian=False, flight_ring_s=0.0,
    )  # fmt: skip
    with LocalStack(options) as stack:
        stack.start(timeout=60.0)
        stack.wait_running(30.0)
        assert all(isinstance(c.proc, subprocess.Popen) for c in stack.children)
        assert {psutil.Process(c.proc.pid).ppid() for c in stack.children} == {os.getpid()}
        codes = stack.stop()
    assert set(codes.values()) == {0}, codes
