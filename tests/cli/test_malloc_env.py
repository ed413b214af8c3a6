"""glibc keeps the memory a photo's work frees for the next photo (``findme.malloc_env``):
a worker thread that allocates and frees the same large arrays photo after photo no longer
has them faulted in afresh each time; a user's own allocator settings are left to glibc."""

import subprocess
import sys

import pytest

from findme import malloc_env
from tests.numeric_envs import ROOT


def test_both_thresholds_are_set_to_keep_bytes():
    calls = []
    assert malloc_env.keep_freed_memory({}, lambda p, v: calls.append((p, v)) or 1) == "set"
    assert calls == [(malloc_env.M_MMAP_THRESHOLD, 32 << 20), (malloc_env.M_TRIM_THRESHOLD, 32 << 20)]


def test_a_users_own_settings_are_left_to_glibc():
    for var in malloc_env.USER_SETTINGS:
        calls = []
        assert malloc_env.keep_freed_memory({var: "1"}, lambda p, v: calls.append(p) or 1) \
            == "user settings"
        assert calls == []


def test_a_value_glibc_refuses_is_reported():
    assert malloc_env.keep_freed_memory({}, lambda p, v: 0) == "refused"


def test_the_command_sets_them_before_any_work(monkeypatch):
    from findme import cli
    seen = []
    monkeypatch.setattr(malloc_env, "keep_freed_memory", lambda: seen.append(True))
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    assert seen == [True]


FAULTS = """
import resource, sys, threading
import numpy as np
if sys.argv[1] == "keep":
    from findme.malloc_env import keep_freed_memory
    assert keep_freed_memory({}) == "set"
out = []
def photo():
    # a photo's work: six 4 MB arrays alive at once (6 x 1,024 pages), all freed after
    arrays = [np.ones(1 << 19) for _ in range(6)]
    return sum(a.sum() for a in arrays)
def photos():
    for _ in range(3):     # warm: the heap grows to the working set once
        photo()
    f0 = resource.getrusage(resource.RUSAGE_THREAD).ru_minflt
    for _ in range(20):
        photo()
    out.append(resource.getrusage(resource.RUSAGE_THREAD).ru_minflt - f0)
t = threading.Thread(target=photos); t.start(); t.join()
print(out[0])
"""


def _faults(mode: str) -> int:
    p = subprocess.run([sys.executable, "-c", FAULTS, mode], cwd=ROOT, capture_output=True,
                       text=True, timeout=120, env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)})
    assert p.returncode == 0, p.stderr
    return int(p.stdout)


@pytest.mark.skipif(malloc_env._glibc_mallopt() is None,
                    reason="glibc's mallopt only: this C library manages its memory its own way")
def test_a_worker_threads_large_arrays_are_reused_not_faulted_in_again():
    kept, default = _faults("keep"), _faults("default")
    pages = 20 * 6 * 1024
    assert default >= 0.25 * pages         # glibc gives the freed heap top back: faulted again
    assert kept <= 0.05 * pages            # reused: a few pages at most
