"""Entry point: parse arguments, configure logging, turn errors into one-line messages.

Each subcommand lives in its own module under ``armstereo.cli`` and exposes
``register(subparsers)``, which adds its parser and sets ``func(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from armstereo import __version__
from armstereo.errors import ArmstereoError

SUBCOMMANDS = ["demo", "capture", "inspect", "reconstruct", "stereo", "eval", "plan", "sweep",
               "fuse"]

log = logging.getLogger("armstereo")


def build_parser() -> argparse.ArgumentParser:
    """The full parser with every subcommand module that is present."""
    parser = argparse.ArgumentParser(
        prog="armstereo",
        description="A robot arm with a wrist camera as a 3D scanner.",
    )
    parser.add_argument("--version", action="version", version=f"armstereo {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show full tracebacks and debug logging")
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"armstereo.cli.{name}_cmd")
        except ModuleNotFoundError as err:
            if err.name != f"armstereo.cli.{name}_cmd":
                raise
            continue
        module.register(sub)
    return parser


def _configure_logging(debug: bool, quiet: bool) -> None:
    level = logging.DEBUG if debug else logging.WARNING if quiet else logging.INFO
    logging.basicConfig(level=level, format="%(message)s" if not debug else
                        "%(levelname)s %(name)s: %(message)s", stream=sys.stderr)


def _move_global_flags_first(argv: list[str]) -> list[str]:
    """Accept ``--debug``/``-q`` anywhere on the line, not only before the subcommand."""
    flags = [a for a in argv if a in ("--debug", "-q", "--quiet")]
    return flags + [a for a in argv if a not in ("--debug", "-q", "--quiet")]


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (also used by ``sys.exit``)."""
    argv = _move_global_flags_first(list(sys.argv[1:] if argv is None else argv))
    parser = build_parser()
    args = parser.parse_args(argv)
    _configure_logging(args.debug, args.quiet)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except ArmstereoError as err:
        if args.debug:
            raise
        print(f"armstereo {args.command}: error: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        if args.debug:
            raise
        print(f"armstereo {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as err:  # noqa: BLE001 - last line of defence: one line, no traceback
        if args.debug:
            raise
        print(f"armstereo {args.command}: internal error: {type(err).__name__}: {err} "
              "(run with --debug for the traceback)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
