"""The ``armstereo`` command line: one console script with subcommands."""
