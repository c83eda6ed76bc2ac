"""Command-line flags of the matcher, generated from its options' fields.

Every matcher flag is declared once, on its :class:`~armstereo.reconstruct.stereo_options.
BirchfieldOptions` field (:func:`armstereo.flags.option`), as the backends' flags are on their
config fields (:mod:`.backend_flags`); a field's ``type`` check raises ArmstereoError and is
turned into argparse's one-line error here. Each flag sets the attribute named as its field,
with the field's default, so :func:`matcher_from_args` makes the options object from them.
"""

from __future__ import annotations

import argparse
import dataclasses

from armstereo.cli import args as args_
from armstereo.reconstruct.stereo_options import BirchfieldOptions, StereoOptions, options_for


def flag_fields(names: tuple[str, ...] | None = None) -> list[dataclasses.Field]:
    """The BirchfieldOptions fields that are command-line flags (only ``names``, in their
    order, if given)."""
    fields = {f.name: f for f in dataclasses.fields(BirchfieldOptions) if "flag" in f.metadata}
    return list(fields.values()) if names is None else [fields[n] for n in names]


def add_matcher_flags(p: argparse.ArgumentParser | argparse._ArgumentGroup, *,
                      names: tuple[str, ...] | None = None, help_prefix: str = "") -> None:
    """Add the matcher's flags (those of ``names`` only, in that order, if given) to ``p``
    (in the fields' order otherwise); each help text
    starts with ``help_prefix`` (e.g. ``"birchfield: "`` outside a group of their own)."""
    for f in flag_fields(names):
        kwargs = dict(f.metadata["argparse"])
        if "type" in kwargs:
            kwargs["type"] = args_.checked(kwargs["type"])
        p.add_argument(f.metadata["flag"], dest=f.name, default=f.default,
                       help=help_prefix + f.metadata["help"], **kwargs)


def matcher_from_args(args: argparse.Namespace, method: str) -> StereoOptions:
    """The options of ``method``: for Birchfield-Tomasi those of the matcher flags
    :func:`add_matcher_flags` added (the others at their defaults), for SGBM its defaults
    (the flags are Birchfield-Tomasi's and do not apply)."""
    if method != "birchfield":
        return options_for(method)
    given = {f.name: getattr(args, f.name) for f in flag_fields() if hasattr(args, f.name)}
    return BirchfieldOptions(**given)
