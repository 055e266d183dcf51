"""snapwarn SDK: ``Client`` / ``AsyncClient`` over httpx2 and the shared pydantic schemas.

Importing it loads no FastAPI, numpy, scipy or numba; numpy arrays are accepted anywhere a
list of numbers is, and returned by :meth:`Client.signal_data` where numpy is installed.
Results are the typed models of ``service.schemas`` (``det.modes[0].sigma2``); every error is a
:class:`SnapwarnError` (``ApiError`` for a problem answer, ``TransportFailed`` for no answer).
"""

from service.client._clients import AsyncClient, Client
from service.client.errors import (
    ApiError,
    BadRequest,
    Conflict,
    InvalidInput,
    JobFailed,
    NotFound,
    NotImplementedOnServer,
    PayloadTooLarge,
    ServerError,
    SnapwarnError,
    TransportFailed,
    Unauthorized,
    UnsupportedMediaType,
    WaitTimeout,
)

__all__ = [
    "ApiError",
    "AsyncClient",
    "BadRequest",
    "Client",
    "Conflict",
    "InvalidInput",
    "JobFailed",
    "NotFound",
    "NotImplementedOnServer",
    "PayloadTooLarge",
    "ServerError",
    "SnapwarnError",
    "TransportFailed",
    "Unauthorized",
    "UnsupportedMediaType",
    "WaitTimeout",
]
