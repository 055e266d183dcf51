"""One app in-process (ASGI, lifespan run, thread pools) for the contract tests."""

from __future__ import annotations

from collections.abc import AsyncIterator

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


