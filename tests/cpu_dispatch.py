"""Two ways this machine may round: as an old x86-64 CPU (x86-64-v2: SSE4.2, no AVX2,
no FMA) would, or with every feature of the CPU (as the libraries choose by themselves).

NumPy reads ``NPY_DISABLE_CPU_FEATURES`` at import (the dispatched features named there
are not used; NumPy's documentation, "CPU build options: runtime dispatch"); OpenBLAS
reads ``OPENBLAS_CORETYPE`` when it loads (a ``DYNAMIC_ARCH`` build, as NumPy's wheels
ship); glibc reads ``GLIBC_TUNABLES`` at start (``glibc.cpu.hwcaps``: CPU features its
libm's variants are not to use, so ``math.sin`` is not its FMA variant). All only work in
a new process: use these environments for subprocesses.
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import re
import subprocess
import sys

VARIABLES = (
    "NPY_DISABLE_CPU_FEATURES",
    "NPY_ENABLE_CPU_FEATURES",
    "OPENBLAS_CORETYPE",
    "GLIBC_TUNABLES",
)
OLD_BLAS_KERNEL = "Nehalem"
"""OpenBLAS's kernel for SSE4.2 (x86-64-v2, NumPy's x86-64 baseline)."""
OLD_LIBM = "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F"
"""glibc without the features of its libm's faster variants."""


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
    """NumPy's dispatch limited to its baseline; OpenBLAS on :data:`OLD_BLAS_KERNEL` and
    glibc as :data:`OLD_LIBM` (x86-64 only: other machines name them differently)."""
    env = native_env()
    env["NPY_DISABLE_CPU_FEATURES"] = " ".join(dispatched_features())
    if platform.machine().lower() in ("x86_64", "amd64"):
        env["OPENBLAS_CORETYPE"] = OLD_BLAS_KERNEL
        env["GLIBC_TUNABLES"] = OLD_LIBM
    return env


PROBE = """
import json
try:
    from numpy._core import _multiarray_umath as m
except ImportError:  # NumPy 1
    from numpy.core import _multiarray_umath as m
import math, struct
libm = 0
for i in range(20000):
    x = 0.1 * i + 0.123456789
    y = math.sin(x) * math.cos(x) + math.atan2(x, 1.3) + math.exp(-x / 1e5)
    libm ^= struct.unpack("<Q", struct.pack("<d", y))[0]
found = sorted(f for f in m.__cpu_dispatch__ if m.__cpu_features__.get(f))
print(json.dumps([found, hex(libm)]))
"""
"""Prints the dispatched features in use (as ``numpy.show_runtime()`` finds them) and a
hash of libm's results."""


def runtime(env: dict[str, str]) -> tuple[list[str], str, str]:
    """In a process with ``env``: the dispatched features NumPy uses (what
    ``numpy.show_runtime()`` lists as found), the kernel OpenBLAS chose ("" when it does
    not say) and a hash of glibc's ``sin``, ``cos``, ``atan2``, ``exp`` over 20,000
    values (it changes with the FMA variants)."""
    out = subprocess.run(
        [sys.executable, "-c", PROBE],
        env=env | {"OPENBLAS_VERBOSE": "2"},
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    kernel = re.search(r"Core: (\w+)", out.stderr)
    found, libm = json.loads(out.stdout)
    return found, kernel.group(1) if kernel else "", libm
