"""Find Me: the command line, I/O and tools around the pure ``findme_core`` algorithms."""

from .blas_env import drop_unrunnable_kernel

__version__ = "0.1.0"

# before anything imports numpy (every ``findme`` command and ``python -m findme.cli`` come
# through here): OpenBLAS reads its forced kernel once, when numpy loads it
drop_unrunnable_kernel()
