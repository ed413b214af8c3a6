"""An ``OPENBLAS_CORETYPE`` this CPU cannot run is dropped before numpy loads OpenBLAS.

OpenBLAS reads ``OPENBLAS_CORETYPE`` once, when numpy loads it, and a forced kernel is used
whatever the CPU: SkylakeX's AVX-512 code on a CPU without AVX-512 stops the process on an
illegal instruction (SIGILL, exit 132, nothing printed), in ``findme regress`` as anywhere.
Its own detection falls back to Haswell's kernels there; so does this, saying so on stderr.
It must run before numpy is imported, which is why ``findme/__init__.py`` calls it (and
the tools that import numpy first call it themselves).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

#: OpenBLAS kernel (lower case) -> /proc/cpuinfo flags its code needs
KERNEL_NEEDS = {
    "skylakex": ("avx512f", "avx512bw", "avx512vl"),
    "cooperlake": ("avx512f", "avx512bw", "avx512vl", "avx512_bf16"),
    "sapphirerapids": ("avx512f", "avx512bw", "avx512vl", "avx512_bf16"),
    "haswell": ("avx2", "fma"),
    "zen": ("avx2", "fma"),
    "sandybridge": ("avx",),
}


def cpu_flags(cpuinfo: str | Path = "/proc/cpuinfo") -> set[str] | None:
    """The CPU's feature flags from ``cpuinfo``'s first ``flags`` line; None where unknown
    (no such file: not Linux)."""
    try:
        text = Path(cpuinfo).read_text()
    except OSError:
        return None
    line = next((x for x in text.splitlines() if x.startswith("flags")), None)
    return None if line is None else set(line.partition(":")[2].split())


def missing(kernel: str, flags: set[str]) -> list[str]:
    """The flags OpenBLAS's ``kernel`` needs that ``flags`` lacks ([] for a kernel not in
    ``KERNEL_NEEDS``: OpenBLAS itself says what it makes of an unknown name)."""
    return [f for f in KERNEL_NEEDS.get(kernel.strip().lower(), ()) if f not in flags]


def drop_unrunnable_kernel(environ=None, flags: set[str] | None = None,
                           stderr=None) -> str | None:
    """Remove ``OPENBLAS_CORETYPE`` from ``environ`` (default ``os.environ``) when this CPU
    (``flags``, default ``cpu_flags()``) cannot run that kernel, and say so on ``stderr``;
    returns the message, or None when it was kept (or the flags are unknown)."""
    environ = os.environ if environ is None else environ
    kernel = environ.get("OPENBLAS_CORETYPE")
    flags = cpu_flags() if flags is None else flags
    if not kernel or flags is None:
        return None
    lacking = missing(kernel, flags)
    if not lacking:
        return None
    del environ["OPENBLAS_CORETYPE"]
    msg = (f"findme: OPENBLAS_CORETYPE={kernel} is ignored: this CPU lacks "
           f"{', '.join(lacking)}, which OpenBLAS's {kernel} kernels need (forced, they stop "
           "the process on an illegal instruction); OpenBLAS picks this CPU's own kernel\n")
    (sys.stderr if stderr is None else stderr).write(msg)
    return msg
