"""The `rtchannel` command line: a thin layer over the Python API, one module per command.

Errors: user errors (`UserError`, the `InputError` family and pydantic validation errors collected in
`rtchannel.errors.USER_ERRORS`, an OSError naming a file) are one line on stderr with exit status 2.
Anything else is a bug: one line saying so, exit status 1, and the traceback with ``--debug`` or
``RTCHANNEL_DEBUG=1``. Command modules import their heavy dependencies inside the command, so
`rtchannel simulate --backend points` never loads torch or Mitsuba.
"""
from __future__ import annotations

import argparse
import os
import sys
import warnings

from pydantic import ValidationError

from processing.errors import one_line
from rtchannel.cli.common import EXIT_USAGE, OneLineParser, UserError, validation_line
from rtchannel.errors import USER_ERRORS

EXIT_BUG = 1
DEBUG_ENV = "RTCHANNEL_DEBUG"


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    from rtchannel.cli.bench import add_bench
    from rtchannel.cli.classify import add_classifier_commands
    from rtchannel.cli.compare import add_compare
    from rtchannel.cli.data import add_data
    from rtchannel.cli.dataset import add_dataset
    from rtchannel.cli.ensemble import add_ensemble
    from rtchannel.cli.render import add_render
    from rtchannel.cli.robustness import add_robustness
    from rtchannel.cli.simulate import add_simulate
    from rtchannel.cli.transfer import add_transfer

    parser = OneLineParser(prog="rtchannel", description="Motion-capture driven MIMO radar simulator.")
    parser.add_argument("--debug", action="store_true", help="on an internal error, print the full traceback "
                        f"(also: {DEBUG_ENV}=1)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (add_simulate, add_render, add_dataset, add_classifier_commands, add_transfer, add_ensemble,
                add_robustness, add_compare, add_bench, add_data):
        add(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help (0) or a bad argument (2, one line already printed)
        return e.code if isinstance(e.code, int) else EXIT_USAGE

    def one_line_warning(message, category, filename, lineno, file=None, line=None):
        print(f"warning: {message}", file=sys.stderr)

    warnings.showwarning = one_line_warning
    try:
        return args.func(args)
    except UserError as e:
        print(f"error: {one_line(e, 500)}", file=sys.stderr)
    except ValidationError as e:
        print(f"error: {validation_line(e, 'invalid value')}", file=sys.stderr)
    except USER_ERRORS as e:  # every reader's InputError: one line naming file and line/field
        print(f"error: {one_line(e, 500)}", file=sys.stderr)
    except OSError as e:  # unreadable input, unwritable output, full disk: name the file, no traceback
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        print(f"error: {where}{one_line(e.strerror or e, 500)}", file=sys.stderr)
    except Exception as e:  # noqa: BLE001 - not the user's fault: a bug, said as such
        if args.debug or os.environ.get(DEBUG_ENV, "") not in ("", "0"):
            raise
        print(f"error: internal error (a bug in rtchannel, not in your input): {type(e).__name__}: "
              f"{one_line(e, 300)}; run again with --debug or {DEBUG_ENV}=1 for the traceback", file=sys.stderr)
        return EXIT_BUG
    return EXIT_USAGE


# Commands after which the console script ends the process at once (`run`): their outputs are written
# atomically (closed and fsynced) before `main` returns and they leave no child processes behind.
FAST_EXIT_COMMANDS = frozenset({"simulate"})


def run(argv: list[str] | None = None) -> int:
    """The console script (`rtchannel`, `python -m rtchannel[.cli]`): `main`, then, after a command of
    `FAST_EXIT_COMMANDS`, the process ends at once (`os._exit`) once stdout and stderr are flushed.

    Why: interpreter finalisation (tearing down every loaded module; Dr.Jit/LLVM, numba, scipy and matplotlib
    for a facets run) took longer than writing all the figures: measured 0.35-0.4 s for `simulate --backend
    points` and 0.9-1.3 s for `--backend facets` on a loaded 2-core machine (benchmarks/bench_startup.py
    --split, "interpreter exit"). Skipped with it are atexit handlers; none of the libraries `simulate`
    loads registers one with an effect outside the process (numba's shutdown flag, h5py's converter
    registry, tqdm's monitor; Dr.Jit and numba write their kernel caches when compiling). Library callers
    of `main` (tests, scripts) keep a normal interpreter exit.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    rc = main(argv)
    if argv and argv[0] in FAST_EXIT_COMMANDS:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe: nothing more can be written anyway
                pass
        os._exit(rc)
    return rc


__all__ = ["main", "run", "build_parser", "UserError", "EXIT_USAGE", "EXIT_BUG", "DEBUG_ENV", "USER_ERRORS",
           "FAST_EXIT_COMMANDS"]
