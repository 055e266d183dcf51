"""The REST API: ``create_app(settings)`` (FastAPI) and ``export_openapi(path)``.

Imports point one way: this package calls ``sim`` and ``service.analysis`` only through
``service.api.numerics``; the numerics never import it.
"""

from service.api.app import create_app, export_openapi, openapi_document
from service.api.settings import Settings

__all__ = ["Settings", "create_app", "export_openapi", "openapi_document"]
