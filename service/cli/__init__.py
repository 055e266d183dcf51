"""`snapwarn` command line.

Each area registers its sub-commands from its own module (``register(subparsers)``), so the
simulators, the analysis and the service grow their commands independently. With ``--json``
every command prints exactly one JSON document on stdout; progress goes to stderr.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from service.cli._common import CliError, emit_error


def build_parser() -> argparse.ArgumentParser:
    from service.cli import analysis_cmds, service_cmds, sim_cmds

    parser = argparse.ArgumentParser(
        prog="snapwarn",
        description="Early warning of shape transitions of elastic strips.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    from service.cli import atlas_cmds

    for module in (sim_cmds, analysis_cmds, service_cmds, atlas_cmds):
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        emit_error(str(exc), json_mode=getattr(args, "json", False))
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
