"""What the stack's forkserver imports once (:mod:`manus_stack.forks`): every service
``manus up`` starts, and numba's kernels loaded from its cache (filled by then:
:class:`~manus_stack.up.LocalStack` calls :func:`manus.validity.warm_up` before it starts
anything). Imported for its effect; a forked service finds all of it done."""

from __future__ import annotations

import importlib

from manus.validity import warm_up

SERVICES = ("router", "record", "sim", "bridge", "guardian", "planner", "controller", "sequencer")
"""The ``manus`` subcommands whose modules are imported (the viewer is not: rarely started,
and its Foxglove server is its own)."""


def _load() -> None:
    from manus_stack.cli import COMMANDS

    for name in SERVICES:
        importlib.import_module(COMMANDS[name][0])
    warm_up()


_load()
