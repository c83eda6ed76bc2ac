"""Config fields that are also command-line flags.

A config dataclass (a backend's ``drivers/<name>/config.py``, an options type) marks a field as
a flag through its metadata, made with :func:`option`; the command line
(``armstereo.cli.backend_flags``) reads that metadata and builds the argparse flag, so a flag is
written once, beside the field it sets. This sits at the bottom of the layers so that drivers
and library options can use it without importing anything above them.
"""

from __future__ import annotations

from typing import Any


def option(flag: str, help: str, **argparse_kwargs: Any) -> dict[str, Any]:  # noqa: A002
    """Field metadata making a config field a command-line flag: ``field(default=...,
    metadata=option("--exposure", "exposure in the backend's units", type=float))``."""
    return {"flag": flag, "help": help, "argparse": argparse_kwargs}
