"""`snapwarn` command line.

Each area registers its sub-commands from its own module (``register(subparsers)``), so the
simulators, the analysis and the service grow their commands independently. With ``--json``
every command prints exactly one JSON document on stdout; progress goes to stderr.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn

from service.cli._common import CliError, emit_error, error_from


class _UsageError(CliError):
    def __init__(self, message: str, parser: argparse.ArgumentParser) -> None:
        super().__init__(message)
        self.parser = parser


class _Parser(argparse.ArgumentParser):
    """argparse, with usage errors raised (so that ``--json`` can answer them as JSON)."""

    def error(self, message: str) -> NoReturn:
        raise _UsageError(message, self)


def build_parser() -> argparse.ArgumentParser:
    from service.cli import analysis_cmds, service_cmds, sim_cmds

    parser = _Parser(
        prog="snapwarn",
        description="Early warning of shape transitions of elastic strips.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    from service.cli import atlas_cmds, watch_cmds

    for module in (sim_cmds, analysis_cmds, service_cmds, atlas_cmds, watch_cmds):
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        if "--json" not in argv:
            exc.parser.print_usage(sys.stderr)
        emit_error(f"{exc.parser.prog}: {exc}", json_mode="--json" in argv, status=400)
        return 2
    json_mode = getattr(args, "json", False)
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        emit_error(str(exc), json_mode=json_mode, field=exc.field, value=exc.value,
                   status=exc.status)  # fmt: skip
        return 2
    except Exception as exc:
        err = error_from(exc)  # the numerics' and the reader's errors name their field
        if err is not None:
            emit_error(str(err), json_mode=json_mode, field=err.field, value=err.value,
                       status=err.status)  # fmt: skip
            return 2
        if not json_mode:
            raise  # people get the traceback
        emit_error(f"{type(exc).__name__}: {exc}", json_mode=True, status=500)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
