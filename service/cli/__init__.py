"""`snapwarn` command line.

Each area registers its sub-commands from its own module (``register(subparsers)``), so the
simulators, the analysis and the service grow their commands independently. With ``--json``
every command prints exactly one JSON document on stdout; progress goes to stderr.
"""

from __future__ import annotations

import argparse
import gc
import os
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


#: Each command's module (its ``register`` adds it); a test checks this against the modules.
COMMANDS = {
    **dict.fromkeys(("bifurcation", "equilibria", "spectrum", "normal-form", "simulate",
                     "snap"), "sim_cmds"),  # fmt: skip
    **dict.fromkeys(("detect", "predict", "warn", "sweep", "demo"), "analysis_cmds"),
    **dict.fromkeys(("serve", "keys", "db", "worker", "openapi"), "service_cmds"),
    "atlas": "atlas_cmds",
    "watch": "watch_cmds",
}
_MODULES = ("sim_cmds", "analysis_cmds", "service_cmds", "atlas_cmds", "watch_cmds")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every command, or with ``command`` (a name of :data:`COMMANDS`) only of the
    commands its module registers: a command's run does not import and build the others'
    (~30 ms CPU); the top-level help and an unknown command get the whole parser."""
    import importlib

    parser = _Parser(
        prog="snapwarn",
        description="Early warning of shape transitions of elastic strips.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    names = (COMMANDS[command],) if command in COMMANDS else _MODULES
    for name in names:
        importlib.import_module(f"service.cli.{name}").register(sub)
    return parser


#: Commands over one record or one table, whose numerics run as the API's analysis workers do:
#: one BLAS thread (a record's matrices are small; starting and spinning threads cost ~20 ms
#: CPU of a ``detect``). The user's own setting wins; set before numpy is imported.
ONE_BLAS_THREAD = ("detect", "predict")
_BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


#: Commands over one record or one table that run with Python's cyclic garbage collector
#: paused (turned back on when they return: ``main`` may run inside a longer-lived process).
#: In a ``snapwarn detect`` it made ~150 collections, one of them full, over the objects the
#: imports of numpy and numba leave alive: ~55 ms CPU, for cycles the command hardly makes
#: (the peak memory is the same on a warm kernel cache, ~60 MB more when numba compiles).
#: Run as the program (``argv`` from ``sys.argv``), the objects alive at the end are frozen
#: (``gc.freeze``) before the collector is turned back on: the interpreter's exit then does
#: not walk them in one more full collection (~25 ms).
PAUSE_GC = ("detect", "predict")


def main(argv: Sequence[str] | None = None) -> int:
    program = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in PAUSE_GC and gc.isenabled():
        gc.disable()
        try:
            return _main(argv)
        finally:
            if program:
                gc.freeze()
            gc.enable()
    return _main(argv)


def _main(argv: list[str]) -> int:
    if argv and argv[0] in ONE_BLAS_THREAD and "numpy" not in sys.modules:
        for var in _BLAS_THREADS:
            os.environ.setdefault(var, "1")
    parser = build_parser(argv[0] if argv else None)
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
