"""``manus bench [NAME ...]``: run benchmarks and print their figures as one JSON object."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time

from manus_stack.bench import BENCHES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Bench names (default: every quick one) and ``--quick``."""
    parser.add_argument(
        "names",
        nargs="*",
        choices=[*BENCHES, []],
        metavar="NAME",
        help=f"benchmarks to run: {', '.join(BENCHES)} (default: the quick ones: "
        f"{', '.join(n for n, (_, q) in BENCHES.items() if q)})",
    )
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (smoke test)")
    parser.add_argument("-o", "--output", help="also write the JSON to this file")
    parser.add_argument("--minutes", type=float, help="chaos: length of the soak [min]")
    parser.add_argument("--seed", type=int, help="chaos: seed of the fault schedule")
    parser.add_argument(
        "--faults", help="chaos: only these fault kinds (comma-separated, e.g. bridge_sigkill)"
    )
    parser.add_argument("--tasks", help="chaos: only these tasks (comma-separated, e.g. fold)")


def run(args: argparse.Namespace) -> int:
    """Run the chosen benches; print ``{name: figures}``."""
    names = args.names or [n for n, (_, quick) in BENCHES.items() if quick]
    results: dict[str, object] = {}
    for name in names:
        started = time.perf_counter()
        print(f"bench {name} ...", file=sys.stderr, flush=True)
        module = importlib.import_module(BENCHES[name][0])
        options = {k: getattr(args, k) for k in getattr(module, "OPTIONS", ())}
        results[name] = module.run(quick=args.quick, **options)
        print(f"bench {name}: {time.perf_counter() - started:.1f} s", file=sys.stderr, flush=True)
    text = json.dumps(results, indent=2)
    print(text)
    if args.output:
        with open(args.output, "w") as f:
            f.write(text + "\n")
    return 0
