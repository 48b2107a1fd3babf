"""``manus give OBJECT``: bring the object the arm holds to the hand-over pose near the
user (:mod:`manus_stack.commands.pick`, docs/pick.md)."""

from __future__ import annotations

import argparse

from manus_stack.commands import pick
from schemas.sequencing import StepKind


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``OBJECT``, ``--mode`` and the bus settings."""
    pick.add_object_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Give the object."""
    return pick.run_step(args, StepKind.GIVE)
