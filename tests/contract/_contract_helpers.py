"""Helpers of the contract tests (a module with a unique name, imported by the tests)."""

from __future__ import annotations

import io
import json
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path
from typing import Any


def run_cli(*argv: str) -> tuple[int, Any, str]:
    """``snapwarn ARGV`` in-process: (exit code, the stdout JSON document or text, stderr)."""
    from service.cli import main

    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        rc = main(list(argv))
    text = out.getvalue()
    try:
        doc: Any = json.loads(text)
    except json.JSONDecodeError:
        doc = text
    return rc, doc, err.getvalue()


def upload_file(path: Path, **form: Any) -> dict[str, Any]:
    """The multipart parts of an upload of ``path`` (for ``client.post(files=..., data=...)``)."""
    fields = {k: str(v) for k, v in form.items() if v is not None}
    return {"files": {"file": (path.name, path.read_bytes())}, "data": fields}

