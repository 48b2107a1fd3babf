"""The stack's services forked from one warm interpreter (the standard library's forkserver).

A service started as ``python -m manus_stack.cli NAME`` spends most of its start importing
NumPy, Pinocchio, numba and Zenoh and loading numba's cached kernels: measured, about
1.3 s of CPU each for the simulator, the planner, the controller and the sequencer, some
6 s for a whole stack on a 2-core machine, where the stack's own cycles need a core. So
:class:`~manus_stack.up.LocalStack` starts them through :mod:`multiprocessing`'s
forkserver: a process started once per launching process, which imports every service
(:data:`PRELOAD`: :mod:`manus_stack.warm`) and then forks a child per service. A child
runs as the same command would (:func:`_serve`): its own session, its output to its log,
the given environment and working directory, ``manus_stack.cli.main`` with its
arguments; its exit status is the command's.

What a fork cannot change is what those imports read from the environment then: NumPy's
dispatch (``NPY_*``), numba's cache and threads (``NUMBA_*``), the interpreter's own
(``PYTHON*``) and OpenBLAS's threads. A service asked for with another value of one of
those (:data:`IMPORT_TIME`) starts as a fresh interpreter instead (:func:`forkable`), as
does every service where the forkserver is not available. ``MANUS_FORK=0`` turns the
forks off.
"""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
import types
from collections.abc import Mapping
from pathlib import Path
from typing import Any

PRELOAD = ["manus_stack.warm"]
"""What the forkserver imports once, before it forks a service."""
IMPORT_TIME = ("NPY_", "NUMBA_", "PYTHON", "OPENBLAS_", "OMP_", "MKL_")
"""Prefixes of the environment variables read when the preloaded modules are imported."""
SWITCH = "MANUS_FORK"
"""Environment variable: ``0`` starts every service as a fresh interpreter."""

_context: Any = None
_import_env: dict[str, str] = {}


def _import_time(env: Mapping[str, str]) -> dict[str, str]:
    return {k: v for k, v in env.items() if k.startswith(IMPORT_TIME)}


def forkable(env: Mapping[str, str]) -> bool:
    """Whether a service with environment ``env`` may be forked from the forkserver: forks
    on (:data:`SWITCH`), the forkserver available, and the import-time variables as the
    forkserver's (its own are this process's when it first forks)."""
    if os.environ.get(SWITCH, "1") == "0" or env.get(SWITCH, "1") == "0":
        return False
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return False
    if _context is None:
        return True  # it will take this process's environment
    return _import_time(env) == _import_env


class Forked:
    """A service forked by the forkserver, with what :class:`subprocess.Popen` offers
    the launcher: ``pid``, ``poll``, ``wait`` and ``returncode``.

    Args:
        argv: the command it runs, as a fresh interpreter would (``python -m
            manus_stack.cli NAME ...``): for messages and a restart.
        env: its whole environment.
        log: its output (standard output and error), truncated.
        nice: its niceness (0: as the forkserver's).
    """

    def __init__(self, argv: list[str], env: Mapping[str, str], log: Path, nice: int) -> None:
        global _context
        if _context is None:
            _context = multiprocessing.get_context("forkserver")
            _context.set_forkserver_preload(PRELOAD)
            _import_env.update(_import_time(os.environ))
        self.args = argv
        cli_args = argv[argv.index("manus_stack.cli") + 1 :]
        self._process = _context.Process(
            target=_serve,
            args=(cli_args, dict(env), str(log), nice, os.getcwd()),
            name=cli_args[0],
            daemon=False,
        )
        # The child needs nothing of the launcher's main module, which the forkserver
        # would otherwise run again in it (multiprocessing's "safe importing of main"):
        # a launching script without a __main__ guard would start a stack in every child.
        main = sys.modules["__main__"]
        sys.modules["__main__"] = types.ModuleType("__main__")
        try:
            self._process.start()
        finally:
            sys.modules["__main__"] = main
        self.pid: int = int(self._process.pid)

    @property
    def returncode(self) -> int | None:
        """Its exit status (negative: the signal that ended it), None while it runs."""
        code = self._process.exitcode
        return None if code is None else int(code)

    def poll(self) -> int | None:
        """Its exit status, None while it runs."""
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Wait up to ``timeout`` [s] for it to end; its exit status.

        Raises:
            subprocess.TimeoutExpired: it still runs.
        """
        self._process.join(timeout)
        code = self.returncode
        if code is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        return code


def _serve(cli_args: list[str], env: dict[str, str], log: str, nice: int, cwd: str) -> None:
    """In the forked child: become the command (see the module docstring)."""
    os.setsid()
    if nice:
        from manus.process import lower_priority

        lower_priority(nice)
    os.chdir(cwd)
    os.environ.clear()
    os.environ.update(env)
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(line_buffering=True)
    sys.argv = ["manus", *cli_args]
    from manus_stack.cli import main

    sys.exit(main(cli_args))
