"""Two ways NumPy and OpenBLAS may round on this machine: with NumPy's SIMD dispatch
limited to its baseline and OpenBLAS on its oldest x86-64-v2 kernel (as on an old CPU),
or with every feature of the CPU (as they choose by themselves).

NumPy reads ``NPY_DISABLE_CPU_FEATURES`` at import (the dispatched features named there
are not used; NumPy's documentation, "CPU build options: runtime dispatch"); OpenBLAS
reads ``OPENBLAS_CORETYPE`` when it loads (a ``DYNAMIC_ARCH`` build, as NumPy's wheels
ship). Both only work in a new process: use these environments for subprocesses.
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import re
import subprocess
import sys

VARIABLES = ("NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")
OLD_BLAS_KERNEL = "Nehalem"
"""OpenBLAS's kernel for SSE4.2 (x86-64-v2, NumPy's x86-64 baseline)."""


def dispatched_features() -> list[str]:
    """The CPU features NumPy's build dispatches to at run time (beyond its baseline)."""
    for name in ("numpy._core._multiarray_umath", "numpy.core._multiarray_umath"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        return [str(f) for f in getattr(module, "__cpu_dispatch__", [])]
    return []


def native_env() -> dict[str, str]:
    """This environment without any of :data:`VARIABLES`: every feature of the CPU."""
    return {k: v for k, v in os.environ.items() if k not in VARIABLES}


def baseline_env() -> dict[str, str]:
    """NumPy's dispatch limited to its baseline; OpenBLAS on :data:`OLD_BLAS_KERNEL`
    (x86-64 only: other machines name their kernels differently)."""
    env = native_env()
    env["NPY_DISABLE_CPU_FEATURES"] = " ".join(dispatched_features())
    if platform.machine().lower() in ("x86_64", "amd64"):
        env["OPENBLAS_CORETYPE"] = OLD_BLAS_KERNEL
    return env


PROBE = """
import json
try:
    from numpy._core import _multiarray_umath as m
except ImportError:  # NumPy 1
    from numpy.core import _multiarray_umath as m
print(json.dumps(sorted(f for f in m.__cpu_dispatch__ if m.__cpu_features__.get(f))))
"""
"""Prints the dispatched features in use, as ``numpy.show_runtime()`` finds them."""


def runtime(env: dict[str, str]) -> tuple[list[str], str]:
    """In a process with ``env``: the dispatched features NumPy uses (what
    ``numpy.show_runtime()`` lists as found) and the kernel OpenBLAS chose ("" when it
    does not say)."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE],
        env=env | {"OPENBLAS_VERBOSE": "2"},
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    kernel = re.search(r"Core: (\w+)", out.stderr)
    return json.loads(out.stdout), kernel.group(1) if kernel else ""
