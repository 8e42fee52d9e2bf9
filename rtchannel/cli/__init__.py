"""The `rtchannel` command line: a thin layer over the Python API, one module per command.

Errors in user input (`UserError`, `rtchannel.errors.USER_ERRORS`, OSError naming a file): one line on
stderr, exit status 2. Command modules import their heavy dependencies inside the command, so `rtchannel simulate --backend points` never loads torch or Mitsuba.
"""
from __future__ import annotations

import argparse
import sys
import warnings

from pydantic import ValidationError

from processing.errors import one_line
from rtchannel.cli.common import EXIT_USAGE, OneLineParser, UserError, validation_line
from rtchannel.errors import USER_ERRORS


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    from rtchannel.cli.bench import add_bench
    from rtchannel.cli.classify import add_classifier_commands
    from rtchannel.cli.compare import add_compare
    from rtchannel.cli.dataset import add_dataset
    from rtchannel.cli.render import add_render
    from rtchannel.cli.simulate import add_simulate

    parser = OneLineParser(prog="rtchannel", description="Motion-capture driven MIMO radar simulator.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (add_simulate, add_render, add_dataset, add_classifier_commands, add_compare, add_bench):
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
    except ValueError as e:
        print(f"error: {one_line(e, 500)}", file=sys.stderr)
    except Exception as e:  # noqa: BLE001 - any library failure surfaces as one clear line
        if type(e).__name__ == "LLVMNotFoundError":
            print(f"error: {e}", file=sys.stderr)
        else:
            raise
    return EXIT_USAGE


__all__ = ["main", "build_parser", "UserError", "EXIT_USAGE", "USER_ERRORS"]
