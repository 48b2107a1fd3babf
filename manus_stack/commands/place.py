"""``manus place OBJECT --at X Y Z YAW PITCH ROLL`` or ``--on SURFACE``: put the object
the arm holds down (:mod:`manus_stack.commands.pick`, docs/pick.md)."""

from __future__ import annotations

import argparse

from manus_stack.commands import pick
from schemas.sequencing import StepKind


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``OBJECT``, ``--at`` or ``--on``, ``--mode`` and the bus settings."""
    pick.add_place_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Place the object."""
    return pick.run_step(args, StepKind.PLACE)
