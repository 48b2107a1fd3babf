"""``manus move-to NAME``: move the arm to a named pose on the live stack (``manus reach
--to NAME``: :mod:`manus_stack.commands.reach`)."""

from __future__ import annotations

import argparse

from manus_stack.commands import reach


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``NAME``, the search's seed and speed, ``--mode`` and the bus settings."""
    reach.add_move_to_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Move to the named pose."""
    return reach.run_move_to(args)
