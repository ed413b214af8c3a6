"""Recorded sessions run again: ``replay`` (a recording back on the bus) and ``regress`` (its
inputs through the current services, every result compared with the recorded one). Used by
``findme replay`` / ``findme regress`` (``findme.cli.record``) and ``tools/make_golden.py``."""
