"""glibc's allocator is told to keep the memory a photo's work frees, for the next photo.

A photo's work allocates and frees large arrays: the decoded image, its grey copy, gradient
and edge maps, features (0.3-5 MB each at 640x480). glibc serves a block above its mmap
threshold (128 kB at first, raised as such blocks are freed, but only in the main thread's
heap) with a fresh ``mmap`` and gives it back on ``free``; and it trims a heap's free top
above its trim threshold back to the OS. The services do their work on worker threads, in
heaps of their own, so the next photo's arrays are faulted in page by page again (zeroed by
the kernel): measured in the documented deployment at peak, 7,100 minor page faults a second
in each hypotheses worker, about 1,900 a photo; with the thresholds below, 30 a second. The
same pipeline in one thread: 817 faults a photo against 66, 2.7 ms of kernel time against
0.5 ms.

``keep_freed_memory`` sets both thresholds (``mallopt``) to 32 MiB, the largest mmap
threshold glibc takes on 64-bit: blocks up to that size come from the heaps and are reused;
up to 32 MiB free at a heap's top is kept. A process's RSS is then its peak working set,
not less (the deployment's processes: the same or up to 40 MB more, measured). The user's
own ``MALLOC_*_`` / ``GLIBC_TUNABLES`` settings are left to glibc; other C libraries are left
alone. Called once by ``findme``'s ``main``, before any work.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import platform
from collections.abc import Callable, Mapping

#: mallopt's parameters (glibc's malloc.h)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
#: bytes: glibc's largest mmap threshold on 64-bit (HEAP_MAX_SIZE / 2), and the trim threshold
KEEP_BYTES = 32 << 20
#: environment variables by which a user tunes glibc's allocator himself
USER_SETTINGS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_",
                 "GLIBC_TUNABLES")


def _glibc_mallopt() -> Callable[[int, int], int] | None:
    """glibc's ``mallopt`` (int (int, int)), or None under another C library."""
    if platform.libc_ver()[0] != "glibc":
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None
    fn = getattr(libc, "mallopt", None)
    if fn is not None:
        fn.argtypes, fn.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return fn


def keep_freed_memory(env: Mapping[str, str] = os.environ,
                      mallopt: Callable[[int, int], int] | None = None) -> str:
    """Set glibc's mmap and trim thresholds to ``KEEP_BYTES`` unless ``env`` holds a user's
    own allocator settings (``USER_SETTINGS``). ``mallopt``: glibc's, found when None.

    Returns what was done, one of "set", "user settings", "not glibc", "refused" (glibc
    returned 0: a value it does not take).
    """
    if any(k in env for k in USER_SETTINGS):
        return "user settings"
    fn = mallopt or _glibc_mallopt()
    if fn is None:
        return "not glibc"
    ok = fn(M_MMAP_THRESHOLD, KEEP_BYTES) == 1
    ok = fn(M_TRIM_THRESHOLD, KEEP_BYTES) == 1 and ok
    return "set" if ok else "refused"
