"""Command-line flags of the matchers, generated from their options' fields.

Every matcher flag is declared once, on its :class:`~armstereo.reconstruct.stereo_options.
BirchfieldOptions` or :class:`~armstereo.reconstruct.stereo_options.SgbmOptions` field
(:func:`armstereo.flags.option`), as the backends' flags are on their
config fields (:mod:`.backend_flags`); a field's ``type`` check raises ArmstereoError and is
turned into argparse's one-line error here. Each flag sets the attribute named as its field,
with the field's default, so :func:`matcher_from_args` makes the options object from them.
"""

from __future__ import annotations

import argparse
import dataclasses

from armstereo.cli import args as args_
from armstereo.reconstruct.stereo_options import (
    BirchfieldOptions,
    SgbmOptions,
    StereoOptions,
)


def flag_fields(names: tuple[str, ...] | None = None, *,
                options: type = BirchfieldOptions) -> list[dataclasses.Field]:
    """The fields of ``options`` (BirchfieldOptions or SgbmOptions) that are command-line
    flags (only ``names``, in their order, if given)."""
    fields = {f.name: f for f in dataclasses.fields(options) if "flag" in f.metadata}
    return list(fields.values()) if names is None else [fields[n] for n in names]


def add_matcher_flags(p: argparse.ArgumentParser | argparse._ArgumentGroup, *,
                      names: tuple[str, ...] | None = None, help_prefix: str = "",
                      options: type = BirchfieldOptions) -> None:
    """Add the flags of ``options``' fields (those of ``names`` only, in that order, if
    given) to ``p`` (in the fields' order otherwise); each help text starts with
    ``help_prefix`` (e.g. ``"birchfield: "`` outside a group of their own)."""
    for f in flag_fields(names, options=options):
        kwargs = dict(f.metadata["argparse"])
        if "type" in kwargs:
            kwargs["type"] = args_.checked(kwargs["type"])
        p.add_argument(f.metadata["flag"], dest=f.name, default=f.default,
                       help=help_prefix + f.metadata["help"], **kwargs)


def add_sgbm_flags(p: argparse.ArgumentParser | argparse._ArgumentGroup, *,
                   help_prefix: str = "") -> None:
    """Add SGBM's flags (``--sgbm-mode``, ``--sgbm-presmooth``, ``--sgbm-shifts``)."""
    add_matcher_flags(p, help_prefix=help_prefix, options=SgbmOptions)


def matcher_from_args(args: argparse.Namespace, method: str) -> StereoOptions:
    """The options of ``method`` from the flags :func:`add_matcher_flags` /
    :func:`add_sgbm_flags` added (the fields without a flag at their defaults). The flags of
    the other method are ignored: they do not apply to it."""
    options = BirchfieldOptions if method == "birchfield" else SgbmOptions
    given = {f.name: getattr(args, f.name) for f in flag_fields(options=options)
             if hasattr(args, f.name)}
    return options(**given)
