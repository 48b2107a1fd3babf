"""The whole suite N times in a row beside a bounded CPU hog on every core: per run,
pass or fail, failures, reruns and wall time.

    .venv/bin/python -m tests.tools.under_load --runs 5          # the acceptance figure
    .venv/bin/python -m tests.tools.under_load --runs 1 --hogs 0 # the suite on a quiet machine

Each run is the README's test command without the set-up (``python -m pytest -q`` in the
repository, this interpreter), its output kept in ``--out``. Beside it, ``--hogs``
processes (default: one per CPU) spin at ``--hog-nice`` niceness; each stops by itself
after ``--hog-limit`` seconds whatever happens to this script, and is ended (by its pid)
when the run ends. The load average is sampled during each run. Prints one JSON line
per run and a summary; exits 1 if any run failed or needed a rerun.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HOG = """
import os, sys, time
os.nice(int(sys.argv[2]))
end = time.monotonic() + float(sys.argv[1])
while time.monotonic() < end:
    pass
"""
"""One CPU hog: spins until its time limit [s] (argv 1), at a niceness (argv 2)."""
COUNTS = re.compile(r"(\d+) (passed|failed|errors?|rerun|skipped|xfailed|xpassed)")


def start_hogs(count: int, limit_s: float, nice: int) -> list[subprocess.Popen[bytes]]:
    """``count`` hogs, each ending by itself after ``limit_s``."""
    return [
        subprocess.Popen([sys.executable, "-c", HOG, str(limit_s), str(nice)]) for _ in range(count)
    ]


def stop(procs: list[subprocess.Popen[bytes]]) -> None:
    """End the hogs this script started (by pid), then reap them."""
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        p.wait(timeout=10)


def summary_counts(text: str) -> dict[str, int]:
    """The counts of pytest's last summary line (``N passed, M rerun in ...``)."""
    lines = [li for li in text.splitlines() if re.search(r" in [\d.]+s", li) and COUNTS.search(li)]
    if not lines:
        return {}
    return {kind.rstrip("s") if kind == "errors" else kind: int(n)
            for n, kind in COUNTS.findall(lines[-1])}  # fmt: skip


def one_run(index: int, args: argparse.Namespace) -> dict[str, object]:
    """Run the suite once beside the hogs; what happened."""
    log = args.out / f"run{index}.log"
    hogs = start_hogs(args.hogs, args.hog_limit, args.hog_nice)
    loads: list[float] = []
    start = time.monotonic()
    try:
        with log.open("w") as out:
            suite = subprocess.Popen(
                [sys.executable, "-m", "pytest", "-q", *args.pytest_args],
                cwd=ROOT,
                stdout=out,
                stderr=subprocess.STDOUT,
            )
            while suite.poll() is None:
                loads.append(os.getloadavg()[0])
                time.sleep(5.0)
    finally:
        stop(hogs)
    wall = time.monotonic() - start
    text = log.read_text(errors="replace")
    counts = summary_counts(text)
    reruns = re.search(r"reruns: (\d+)", text)
    return {
        "run": index,
        "ok": suite.returncode == 0,
        "exit": suite.returncode,
        "passed": counts.get("passed", 0),
        "failed": counts.get("failed", 0) + counts.get("error", 0),
        "reruns": int(reruns.group(1)) if reruns else counts.get("rerun", 0),
        "rerun_tests": re.findall(r"^RERUN (\S+):", text, re.MULTILINE),
        "failed_tests": re.findall(r"^FAILED (\S+)", text, re.MULTILINE),
        "wall_s": round(wall, 1),
        "load_avg_1min": {
            "mean": round(sum(loads) / len(loads), 2) if loads else None,
            "max": round(max(loads), 2) if loads else None,
        },
        "hogs": args.hogs,
        "log": str(log),
    }


def main(argv: list[str] | None = None) -> int:
    """Run the suite ``--runs`` times under load; 1 if any run failed or reran."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=5, help="runs in a row (default 5)")
    parser.add_argument("--hogs", type=int, default=os.cpu_count() or 1,
                        help="CPU hogs beside each run (default: one per CPU)")  # fmt: skip
    parser.add_argument("--hog-nice", type=int, default=0, help="the hogs' niceness (0..19)")
    parser.add_argument("--hog-limit", type=float, default=900.0,
                        help="a hog stops by itself after this long [s] (900)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("runs") / "under-load",
                        help="directory of the runs' logs (default runs/under-load)")  # fmt: skip
    parser.add_argument("pytest_args", nargs="*", help="more pytest arguments (after --)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    results = []
    for i in range(1, args.runs + 1):
        result = one_run(i, args)
        results.append(result)
        print(json.dumps(result), flush=True)
    bad = [r for r in results if not r["ok"] or r["reruns"]]
    walls = [float(str(r["wall_s"])) for r in results]
    print(
        f"{len(results)} run(s) with {args.hogs} hog(s) at nice {args.hog_nice}: "
        f"{len(results) - len(bad)} passed with no rerun; wall {min(walls):.0f}-{max(walls):.0f} s"
    )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
