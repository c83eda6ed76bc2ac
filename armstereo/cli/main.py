"""Entry point: parse arguments, configure logging, turn errors into one-line messages.

Each subcommand lives in its own module under ``armstereo.cli`` and exposes
``register(subparsers)``, which adds its parser and sets ``func(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import sys

from armstereo import __version__
from armstereo.errors import ArmstereoError

SUBCOMMANDS = ["demo", "capture", "inspect", "reconstruct", "stereo", "eval", "plan", "sweep",
               "robot_info", "check", "reconstruct_images", "study", "analyze", "fuse", "scan",
               "calibrate", "export", "import"]

log = logging.getLogger("armstereo")


class OneLineParser(argparse.ArgumentParser):
    """Bad arguments end with one line on stderr (no usage dump) and exit 2, like every other
    error of armstereo; ``--help`` still shows the usage."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The full parser with every subcommand module that is present."""
    parser = OneLineParser(
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
    # force: each call (tests run several commands in one process) logs to today's stderr
    logging.basicConfig(level=level, format="%(message)s" if not debug else
                        "%(levelname)s %(name)s: %(message)s", stream=sys.stderr, force=True)


def _move_global_flags_first(argv: list[str]) -> list[str]:
    """Accept ``--debug``/``-q`` anywhere on the line, not only before the subcommand."""
    flags = [a for a in argv if a in ("--debug", "-q", "--quiet")]
    return flags + [a for a in argv if a not in ("--debug", "-q", "--quiet")]


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (also used by ``sys.exit``)."""
    try:
        return _run(_move_global_flags_first(list(sys.argv[1:] if argv is None else argv)))
    except BrokenPipeError:
        # The reader of our output went away (`armstereo inspect X | head -1`): what it wanted
        # it got; end quietly, like any Unix filter.
        _silence_stdout()
        return 0


def _run(argv: list[str]) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as done:  # --help, --version, or a bad argument (one line printed)
        sys.stdout.flush()  # --help into a closed pipe: BrokenPipeError, handled by main()
        return done.code if isinstance(done.code, int) else 2
    _configure_logging(args.debug, args.quiet)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        code = int(args.func(args) or 0)
        sys.stdout.flush()  # a reader that went away shows here, not at interpreter exit
        return code
    except BrokenPipeError:
        raise
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


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush cannot fail again."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)


if __name__ == "__main__":
    sys.exit(main())
