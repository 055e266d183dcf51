"""Helpers shared by the CLI modules: JSON output, one-line errors, progress on stderr.

With ``--json`` an error is one JSON document on stdout too, with the fields of an RFC 9457
problem (``type``, ``title``, ``status``, ``detail``) and the offending ``field`` and ``value``:
the same document the REST API answers for the same bad input.
"""

from __future__ import annotations

import json
import math
import sys
from typing import Any


class CliError(Exception):
    """A bad argument or input; the message names the option and the value.

    ``field``/``value`` name the input as data, ``status`` is the HTTP status the same problem
    gets from the API (422 invalid input, 413 too large, 415 unknown format).
    """

    def __init__(
        self, message: str, *, field: str | None = None, value: Any = None, status: int = 422
    ) -> None:
        super().__init__(message)
        self.field = field
        self.value = value
        self.status = status


def bad(option: str, value: Any, why: str) -> CliError:
    """Build the one-line error for a bad option value: ``--mu: 'abc' is not a number``."""
    return CliError(f"{option}: {value!r} {why}", field=option, value=value)


def error_from(exc: BaseException, context: str | None = None) -> CliError | None:
    """The CLI error for an error that carries its field as data (a recording, a numerics
    ``ParameterError``), else None. ``context`` (e.g. the file) prefixes the message."""
    from service.analysis.errors import ParameterError as AnalysisParameterError
    from service.recordings import RecordingError, RecordingTooLarge, UnsupportedFormat
    from sim.errors import ParameterError as SimParameterError

    prefix = f"{context}: " if context else ""
    if isinstance(exc, RecordingError):
        status = 415 if isinstance(exc, UnsupportedFormat) else 422
        status = 413 if isinstance(exc, RecordingTooLarge) else status
        return CliError(prefix + str(exc), field=exc.field, value=exc.value, status=status)
    if isinstance(exc, (SimParameterError, AnalysisParameterError)):
        return CliError(prefix + str(exc), field=exc.parameter, value=exc.value)
    return None


def _plain(doc: Any) -> Any:
    from service.convert import plain  # the one strict-JSON cleaner of results

    return plain(doc)


def emit(doc: Any, *, json_mode: bool, text: str | None = None) -> None:
    """Print ``doc`` (a dict or a wire model) as one JSON document (``--json``) or ``text``."""
    if hasattr(doc, "model_dump"):
        doc = doc.model_dump(mode="json")
    if json_mode:
        sys.stdout.write(json.dumps(_plain(doc), allow_nan=False) + "\n")
    else:
        sys.stdout.write(
            (text if text is not None else json.dumps(_plain(doc), indent=2)) + "\n"
        )


_TITLES = {
    400: "Bad request",
    413: "Payload too large",
    415: "Unsupported media type",
    422: "Invalid input",
    500: "Internal error",
}
_SLUGS = {
    400: "bad-request",
    413: "payload-too-large",
    415: "unsupported-media-type",
    422: "invalid-input",
    500: "internal-error",
}


def problem_document(message: str, *, field: str | None, value: Any, status: int) -> dict:
    """The RFC 9457 document of a CLI error (as the API writes it)."""
    from service.convert import plain

    shown = plain(value)
    try:
        json.dumps(shown, allow_nan=False)
    except (TypeError, ValueError):
        shown = repr(value)[:200]
    doc: dict[str, Any] = {
        "type": f"urn:snapwarn:problem:{_SLUGS.get(status, 'invalid-input')}",
        "title": _TITLES.get(status, "Invalid input"),
        "status": status,
        "detail": message,
        "field": field,
        "value": shown,
    }
    if field is not None:
        doc["errors"] = [{"field": field, "value": shown, "message": message}]
    return doc


def emit_error(
    message: str,
    *,
    json_mode: bool,
    field: str | None = None,
    value: Any = None,
    status: int = 422,
) -> None:
    """One line on stderr; with ``json_mode`` also the problem document on stdout."""
    sys.stderr.write(f"snapwarn: error: {message}\n")
    if json_mode:
        doc = problem_document(message, field=field, value=value, status=status)
        sys.stdout.write(json.dumps(doc, allow_nan=False) + "\n")


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


def plot_file(text: str) -> str:
    """argparse ``type`` of ``--plot``: the charts' rule (a .png or .svg file name), imported
    only when the option is given."""
    from service.charts.cli import plot_file as check

    return check(text)


def add_plot_flag(parser: Any, what: str = "a chart of the result") -> None:
    """``--plot FILE.{png,svg}`` on a command (the charts load only when it is given)."""
    parser.add_argument("--plot", metavar="FILE.{png,svg}", type=plot_file, default=None,
                        help=f"also draw {what} into FILE (PNG or SVG)")  # fmt: skip
