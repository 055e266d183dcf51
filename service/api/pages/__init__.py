"""HTML pages served by the API: Jinja2 templates rendered on the server, charts drawn by
matplotlib on the server, static assets (the style sheet, a small refresh script, Swagger UI)
served from this package. Nothing is loaded from another host, so every page works offline.

Pages act as the same caller as the API (``service.api.auth``): a browser that cannot send an
``Authorization`` header stores its key in an HTTP-only cookie through ``/login``; a resource
of another owner answers 404 as on /v1.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import FastAPI
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

from service.api.pages.routes import router

HERE = Path(__file__).parent
STATIC = HERE / "static"

__all__ = ["install", "router"]


def install(app: FastAPI) -> None:
    """Add the pages, ``/static`` and ``/docs`` (Swagger UI from ``/static``) to ``app``.

    The app must be created with ``docs_url=None`` (FastAPI's own page loads Swagger UI from a
    CDN).
    """
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    app.include_router(router)

    @app.get("/docs", include_in_schema=False)
    async def swagger_ui() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=app.openapi_url or "/openapi.json",
            title=f"{app.title} - API",
            swagger_js_url="/static/swagger-ui/swagger-ui-bundle.js",
            swagger_css_url="/static/swagger-ui/swagger-ui.css",
            swagger_favicon_url="/static/favicon.svg",
        )
