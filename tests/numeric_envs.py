"""The numeric environments the suite proves the answers the same under: three OpenBLAS
kernels (``OPENBLAS_CORETYPE``; OpenBLAS inside numpy picks one per CPU, and each rounds
matrix products differently) and numpy's newest SIMD dispatch switched off
(``NPY_DISABLE_CPU_FEATURES=X86_V4``: AVX-512 versions of exp, log, arctan2, ...).

A kernel the CPU cannot run (SkylakeX without AVX-512) is skipped with that reason: there
``findme`` drops it (``findme.blas_env``) and the run would prove nothing about that kernel.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from findme import blas_env

ROOT = Path(__file__).resolve().parents[1]

#: name -> (environment, CPU flags it needs: ``findme.blas_env``'s for OpenBLAS kernels)
ENVIRONMENTS = {
    "Haswell": ({"OPENBLAS_CORETYPE": "Haswell"}, blas_env.KERNEL_NEEDS["haswell"]),
    "SkylakeX": ({"OPENBLAS_CORETYPE": "SkylakeX"}, blas_env.KERNEL_NEEDS["skylakex"]),
    "Sandybridge": ({"OPENBLAS_CORETYPE": "Sandybridge"}, blas_env.KERNEL_NEEDS["sandybridge"]),
    "no-AVX512-numpy": ({"NPY_DISABLE_CPU_FEATURES": "X86_V4"}, ()),
}


def _lacking() -> dict[str, list[str]]:
    """name -> the CPU flags this machine lacks for that environment ([]: it can run it)."""
    flags = blas_env.cpu_flags() or set()
    return {name: [f for f in need if f not in flags] for name, (_, need) in ENVIRONMENTS.items()}


def runnable() -> dict[str, dict]:
    """name -> environment of every numeric environment this CPU can run."""
    return {name: ENVIRONMENTS[name][0] for name, lack in _lacking().items() if not lack}


def env_params():
    """``pytest.param`` per environment, skipped (with the reason) where the CPU lacks what
    the kernel needs."""
    out = []
    for name, missing in _lacking().items():
        env = ENVIRONMENTS[name][0]
        marks = [pytest.mark.skip(reason=f"this CPU lacks {', '.join(missing)}: the {name} "
                                         "kernel cannot run here")] if missing else []
        out.append(pytest.param(env, id=name, marks=marks))
    return out


def run_python(code: str, env: dict, timeout: float = 600.0) -> subprocess.CompletedProcess:
    """``python -c code`` in the repository with ``env`` added to this environment (one
    thread per BLAS: the suite's own setting)."""
    full = {**os.environ, "PYTHONPATH": str(ROOT), "CI": "1", **env}
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=full, text=True,
                          capture_output=True, timeout=timeout)
