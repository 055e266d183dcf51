"""One app in-process (ASGI, lifespan run, thread pools) for the contract tests, and the CLI
run in-process with its stdout captured."""

from __future__ import annotations

import io
import json
import sys
from collections.abc import AsyncIterator, Callable
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path
from typing import Any

import httpx2
import pytest

from service.api import Settings, create_app


@pytest.fixture(scope="module")
def anyio_backend() -> str:
    return "asyncio"


@pytest.fixture(scope="module")
async def api(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[httpx2.AsyncClient]:
    """The real app (store on a SQLite file, analysis and jobs in threads) and a client."""
    db = tmp_path_factory.mktemp("contract") / "api.db"
    settings = Settings(
        db_url=f"sqlite:///{db}",
        executor="thread",
        analysis_workers=1,
        job_workers=1,
        job_poll_s=0.05,
        warm_pool=False,
        api_key=None,
    )
    app = create_app(settings)
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://asgi") as client:
            client.app = app  # type: ignore[attr-defined]
            yield client


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


@pytest.fixture
def cli() -> Callable[..., tuple[int, Any, str]]:
    return run_cli


def upload_file(path: Path, **form: Any) -> dict[str, Any]:
    """The multipart parts of an upload of ``path`` (for ``client.post(files=..., data=...)``)."""
    fields = {k: str(v) for k, v in form.items() if v is not None}
    return {"files": {"file": (path.name, path.read_bytes())}, "data": fields}


assert sys.version_info >= (3, 11)
