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
Measure a room and locate yourself from phone photos: floor-wall boundaries,
3D points with their uncertainty, how the camera moved, the room's floor plan.
"""

EPILOG = """\
"findme COMMAND --help" describes a command and its options. Photos are JPEG,
PNG, WebP, HEIC, AVIF, BMP or TIFF; bad input is one line on stderr, exit 2.
"""


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit status 2, and values such
    as ``-0.05,0.9,0.4`` (a gravity vector) or ``-4,2`` (a pixel) are values, not options."""

    def __init__(self, *args, **kwargs):
        # descriptions are written for the terminal: their line breaks and lists are kept
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")

    def error(self, message):  # noqa: D102 - argparse API
        sys.stderr.write(f"{self.prog}: error: {message} (see --help)\n")
        sys.exit(2)


#: one BLAS/OpenMP/OpenCV thread per process: Find Me scales by processes (service instances,
#: eval jobs), and idle pool threads spin. With OpenBLAS's default threads a 640x480 photo's
#: hypotheses took 46.4 ms of CPU against 22.9 ms, for the same wall time; with OpenCV's
#: default (one thread per core, here 2) 29.0 ms of process CPU against 25.7 ms, for 3 %
#: less wall time, and the pipeline's handlers 16.4 s against 15.2 s (measured)
_ONE_THREAD = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
               "OPENCV_FOR_THREADS_NUM")


def one_thread_per_process() -> None:
    """Set the BLAS and OpenCV thread counts to 1 unless the user set them; must run before
    numpy and cv2 are first imported (``main`` calls it first)."""
    for var in _ONE_THREAD:
        os.environ.setdefault(var, "1")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser: every module of ``registry.COMMAND_MODULES`` registers its commands
    (imported here, not at import time: ``import findme.cli`` loads no numpy), or, for a
    known ``command``, only its module; ``--help`` lists the commands in the groups of
    ``registry.GROUPS``."""
    import importlib

    from .registry import COMMAND_MODULES, COMMANDS, GROUPS
    modules = (COMMANDS[command],) if command in COMMANDS else COMMAND_MODULES
    p = _Parser(prog="findme", usage="findme [-h] [--debug] COMMAND ...", epilog=EPILOG)
    p.add_argument("--debug", action="store_true",
                   help="show the traceback of an internal error (for a bug report)")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser, prog="findme",
                           metavar="COMMAND", help=argparse.SUPPRESS)
    for name in modules:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    p.description = DESCRIPTION + command_list(sub, GROUPS)
    return p


def command_list(sub, groups) -> str:
    """The commands' one-line helps under their group titles, for ``findme --help``."""
    helps = {a.dest: a.help for a in sub._choices_actions}
    width = max(len(name) for name in helps) + 2
    out = []
    for title, names in groups:
        if any(name in helps for name in names):
            out.append(f"\n{title}:")
            out += [f"  {name:{width}s}{helps[name]}" for name in names if name in helps]
    return "\n".join(out) + "\n"


def _command_of(argv: list[str]) -> str | None:
    """The command word of a command line (the first word that is not an option)."""
    return next((a for a in argv if not a.startswith("-")), None)


def main(argv=None) -> int:
    one_thread_per_process()
    from findme.malloc_env import keep_freed_memory
    keep_freed_memory()
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command_of(argv))
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

