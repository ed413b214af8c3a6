"""The ``findme`` command: the top-level parser and ``main``.

Each family of sub-commands lives in its own module of this package, listed in
``registry.COMMAND_MODULES`` (which the parser reads); each module has ``register(sub)``,
which adds its sub-commands and sets their ``func``. The command modules use the shared
option helpers (``options``: camera and value parsing; ``bus_options``: joining a bus;
``web_options``: the gateway's page server) and, beside this package, ``findme.report``
(a session's results on a terminal), ``findme.evaluation`` (``findme eval``) and
``findme.regression`` (``findme replay`` / ``regress``); nothing there imports this package.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

from findme_core.errors import FindmeError


DESCRIPTION = """\
Measure a room and locate yourself from phone photos.

  findme run                      every service on the bundled example (or your photos)
  findme hypotheses PHOTO         the photo's floor-boundary hypotheses, best first
  findme locate PHOTO --point U,V 3D of tapped pixels under a hypothesis
  findme motion PHOTO_A PHOTO_B   how the camera moved between two photos
  findme plan PHOTO...            the room's floor plan from a session of photos
  findme app                      the phone web page, with every service
  findme up                       router + one process per service on this machine
  findme send PHOTOS --connect E  photos to running services, with their results
"""


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit status 2, and values such
    as ``-0.05,0.9,0.4`` (a gravity vector) or ``-4,2`` (a pixel) are values, not options."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")

    def error(self, message):  # noqa: D102 - argparse API
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        sys.exit(2)


#: one BLAS/OpenMP thread per process: Find Me scales by processes (service instances, eval
#: jobs), and OpenBLAS's idle threads spin: with its default threads a 640x480 photo's
#: hypotheses took 46.4 ms of CPU against 22.9 ms, for the same wall time (measured)
_ONE_THREAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_per_process() -> None:
    """Set the BLAS thread counts to 1 unless the user set them; must run before numpy is
    first imported (``main`` calls it first)."""
    for var in _ONE_THREAD:
        os.environ.setdefault(var, "1")


def build_parser() -> argparse.ArgumentParser:
    """The whole parser: every module of ``registry.COMMAND_MODULES`` registers its commands
    (imported here, not at import time: ``import findme.cli`` loads no numpy)."""
    import importlib

    from .registry import COMMAND_MODULES
    p = _Parser(prog="findme", description=DESCRIPTION,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--debug", action="store_true", help="show tracebacks of internal errors")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name in COMMAND_MODULES:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return p


def main(argv=None) -> int:
    one_thread_per_process()
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    # argparse cannot take positional photos after options (``serve capture --session s
    # a.jpg``): leftover non-option words go to the command's photo list, if it has one
    if extra:
        if isinstance(getattr(args, "photos", None), list) and not any(e.startswith("-") for e in extra):
            args.photos.extend(extra)
        else:
            parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return int(args.func(args) or 0)
    except FindmeError as e:
        sys.stderr.write(f"findme {args.command}: error: {e}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        return 130
    except BrokenPipeError:
        # the reader of our output stopped (``findme run | head -3``): not an error; point
        # stdout at /dev/null so that the interpreter's final flush does not complain either
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Exception as e:  # a bug, not bad input: one line unless --debug
        if args.debug:
            raise
        sys.stderr.write(f"findme {args.command}: internal error: {type(e).__name__}: {e} "
                         "(run with --debug for the traceback)\n")
        return 1

