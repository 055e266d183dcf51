"""The REST API: ``create_app(settings)`` (FastAPI) and ``export_openapi(path)``.

Imports point one way: the routers import ``sim`` and ``service.analysis`` plainly and turn
their results into wire models through ``service.convert``; the numerics never import this
package. Names are loaded lazily, so that a pool worker importing ``service.api.executor`` can
configure itself before numpy loads.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Settings", "create_app", "export_openapi", "openapi_document"]


def __getattr__(name: str) -> Any:
    if name in ("create_app", "export_openapi", "openapi_document"):
        from service.api import app

        return getattr(app, name)
    if name == "Settings":
        from service.api.settings import Settings

        return Settings
    raise AttributeError(f"module 'service.api' has no attribute {name!r}")
