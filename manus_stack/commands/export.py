"""``manus export FILE.mcap``: the recorder's exports (:mod:`services.recorder.export_cli`);
``--json`` also writes the viewer's Foxglove channels (:mod:`services.viewer.core`: link
transforms, paths, log, the robot description), so the file opens in Foxglove with the arm
moving (``--no-view``: the recorded channels only)."""

from __future__ import annotations

import argparse

from manus.config import load_arm_config
from services.recorder import export_cli
from services.recorder.reading import Recording
from services.viewer.config import ViewerConfig
from services.viewer.core import ViewerCore


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The recorder's export arguments plus ``--no-view``."""
    export_cli.add_arguments(parser)
    parser.add_argument(
        "--no-view",
        dest="view",
        action="store_false",
        help="with --json: only the recorded channels, not the viewer's Foxglove channels",
    )


def run(args: argparse.Namespace) -> int:
    """Export, with the viewer's channels for ``--json``."""
    if not (args.json and args.view):
        return export_cli.run(args)
    prefix = Recording(args.file).info.prefix or "manus"
    return export_cli.run(args, view=ViewerCore(ViewerConfig(prefix=prefix, arm=load_arm_config())))
