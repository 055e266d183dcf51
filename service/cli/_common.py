"""Helpers shared by the CLI modules: JSON output, one-line errors, progress on stderr."""

from __future__ import annotations

import json
import math
import sys
from typing import Any

import numpy as np


class CliError(Exception):
    """A bad argument or input; the message names the option and the value."""


def bad(option: str, value: Any, why: str) -> CliError:
    """Build the one-line error for a bad option value: ``--mu: 'abc' is not a number``."""
    return CliError(f"{option}: {value!r} {why}")


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_jsonable(v) for v in obj.tolist()]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def emit(doc: dict[str, Any], *, json_mode: bool, text: str | None = None) -> None:
    """Print ``doc`` as one JSON document (``--json``) or ``text`` for people."""
    if json_mode:
        sys.stdout.write(json.dumps(_jsonable(doc), allow_nan=False) + "\n")
    else:
        sys.stdout.write(
            (text if text is not None else json.dumps(_jsonable(doc), indent=2)) + "\n"
        )


def emit_error(message: str, *, json_mode: bool) -> None:
    sys.stderr.write(f"snapwarn: error: {message}\n")


def add_json_flag(parser: Any) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON document on stdout")


def finite(text: str) -> float:
    """argparse type: a finite float (the error names the value; argparse adds the option)."""
    import argparse

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text!r} is not finite")
    return v
