"""An OPENBLAS_CORETYPE the CPU cannot run is dropped, with the reason, before numpy loads
OpenBLAS (``findme.blas_env``); one it can run, or an unknown name, is left to OpenBLAS."""

import io
import subprocess
import sys

from findme import blas_env
from tests.numeric_envs import ROOT

AVX2_ONLY = {"sse4_2", "avx", "avx2", "fma"}


def test_a_kernel_the_cpu_lacks_is_dropped_and_said():
    env, err = {"OPENBLAS_CORETYPE": "SkylakeX", "OTHER": "1"}, io.StringIO()
    msg = blas_env.drop_unrunnable_kernel(env, AVX2_ONLY, err)
    assert env == {"OTHER": "1"}
    assert msg == err.getvalue()
    assert msg.startswith("findme: OPENBLAS_CORETYPE=SkylakeX is ignored: this CPU lacks "
                          "avx512f, avx512bw, avx512vl")


def test_a_runnable_or_unknown_kernel_is_left_alone():
    for kernel in ("haswell", "Sandybridge", "Neoverse9"):
        env, err = {"OPENBLAS_CORETYPE": kernel}, io.StringIO()
        assert blas_env.drop_unrunnable_kernel(env, AVX2_ONLY, err) is None
        assert env == {"OPENBLAS_CORETYPE": kernel} and err.getvalue() == ""


def test_cpu_flags_read_the_first_flags_line(tmp_path):
    f = tmp_path / "cpuinfo"
    f.write_text("processor\t: 0\nflags\t\t: fpu avx avx2\nflags\t\t: ignored\n")
    assert blas_env.cpu_flags(f) == {"fpu", "avx", "avx2"}
    assert blas_env.cpu_flags(tmp_path / "none") is None


def test_the_command_drops_it_before_numpy_loads_openblas():
    """``python -m findme.cli`` with a kernel this CPU cannot run (one it lacks a flag of,
    else an unknown name, which must pass through) runs and says why."""
    flags = blas_env.cpu_flags() or set()
    kernel = next((k for k in blas_env.KERNEL_NEEDS if blas_env.missing(k, flags)), None)
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT),
           "OPENBLAS_CORETYPE": kernel or "NoSuchKernel"}
    p = subprocess.run([sys.executable, "-c", "import findme, os, numpy as np; "
                        "print(os.environ.get('OPENBLAS_CORETYPE')); "
                        "a = np.ones((64, 64)); print((a @ a)[0, 0])"],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    if kernel:
        assert p.stdout.split() == ["None", "64.0"]
        assert f"OPENBLAS_CORETYPE={kernel} is ignored" in p.stderr
    else:
        assert p.stdout.split() == ["NoSuchKernel", "64.0"]
