"""Find Me: the command line, I/O and tools around the pure ``findme_core`` algorithms."""

__version__ = "0.1.0"
