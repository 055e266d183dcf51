"""A bound on the time and the bytes a client takes to send a request's headers (slowloris).

uvicorn bounds the idle time between requests (``timeout_keep_alive``, from the previous
response to the next request's first byte) but not the headers themselves: a client that
connects and sends nothing, or trickles its header lines a byte at a time, holds its connection
(and a file descriptor) for as long as it likes; the app never sees such a request, so no ASGI
middleware can time it out. These HTTP protocol classes (uvicorn's own, httptools or h11, with
one timer added) start a clock when a connection opens and at the first byte of each later
request, and stop it when the request's headers are complete (uvicorn then creates the
request's cycle). Past ``SNAPWARN_HEADER_READ_TIMEOUT_S`` (default 20 s) the connection gets
408 (if the request had begun) and is closed; more than ``SNAPWARN_MAX_HEADER_BYTES`` (default
64 KiB) before the headers end: 431 and closed. The body has its own bound
(``body_read_timeout_s``, in :mod:`service.api.security`).

``snapwarn serve`` passes ``protocol_for(settings.http_impl)`` (an import string: uvicorn's
worker processes import it) as uvicorn's ``http``.
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol

log = logging.getLogger("snapwarn.api")

DEFAULT_TIMEOUT_S = 20.0
DEFAULT_MAX_BYTES = 64 * 1024


def _env_float(name: str, default: float) -> float:
    try:
        value = float(os.environ.get(name, default))
    except ValueError:
        return default
    return value if value > 0 else default


def _refusal(status: int, reason: str, detail: str) -> bytes:
    kind = "request-timeout" if status == 408 else "headers-too-large"
    body = json.dumps({"type": f"urn:snapwarn:problem:{kind}", "title": reason,
                       "status": status, "detail": detail}).encode()  # fmt: skip
    head = (
        f"HTTP/1.1 {status} {reason}\r\ncontent-type: application/problem+json\r\n"
        f"content-length: {len(body)}\r\nconnection: close\r\n\r\n"
    )
    return head.encode("latin-1") + body


class HeaderGuard:
    """Mixed into a uvicorn HTTP protocol class (before it in the bases)."""

    transport: asyncio.Transport
    cycle: Any
    loop: asyncio.AbstractEventLoop

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._header_timeout = _env_float("SNAPWARN_HEADER_READ_TIMEOUT_S", DEFAULT_TIMEOUT_S)
        self._header_max = int(_env_float("SNAPWARN_MAX_HEADER_BYTES", DEFAULT_MAX_BYTES))
        self._header_timer: asyncio.TimerHandle | None = None
        self._header_cycle: Any = None  # the cycle before the request being read
        self._header_bytes = 0

    def _arm(self) -> None:
        self._header_cycle = self.cycle
        self._header_bytes = 0
        self._header_timer = self.loop.call_later(self._header_timeout, self._header_expired)

    def _disarm(self) -> None:
        if self._header_timer is not None:
            self._header_timer.cancel()
            self._header_timer = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)  # type: ignore[misc]
        self._arm()  # a connection that never sends a byte is bounded too

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)  # type: ignore[misc]

    def data_received(self, data: bytes) -> None:
        idle = self.cycle is None or self.cycle.response_complete
        if self._header_timer is None and idle:
            self._arm()  # the first byte of a later request on a kept-alive connection
        super().data_received(data)  # type: ignore[misc]
        if self._header_timer is None:
            return
        if self.cycle is not self._header_cycle:  # the headers are complete
            self._disarm()
            return
        self._header_bytes += len(data)
        if self._header_bytes > self._header_max and not self.transport.is_closing():
            self._disarm()
            self._refuse(431, "Request Header Fields Too Large",
                         f"more than {self._header_max} bytes before the end of the headers "
                         "(setting SNAPWARN_MAX_HEADER_BYTES)")  # fmt: skip

    def _header_expired(self) -> None:
        self._header_timer = None
        if self.transport.is_closing():
            return
        if self._header_bytes == 0:  # nothing of a request yet: an idle connection, closed
            self.transport.close()
            return
        self._refuse(408, "Request Timeout",
                     f"the request's headers took longer than {self._header_timeout:g} s "
                     "(setting SNAPWARN_HEADER_READ_TIMEOUT_S)")  # fmt: skip

    def _refuse(self, status: int, reason: str, detail: str) -> None:
        client = getattr(self, "client", None)
        log.info("%s %s: %s", client, status, detail)
        self.transport.write(_refusal(status, reason, detail))
        self.transport.close()


class GuardedH11(HeaderGuard, H11Protocol):
    """uvicorn's h11 protocol with the header bound."""


try:
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol
except ImportError:  # pragma: no cover - httptools not installed: h11 only
    HttpToolsProtocol = None  # type: ignore[assignment,misc]
    GuardedHttpTools = None
else:

    class GuardedHttpTools(HeaderGuard, HttpToolsProtocol):  # type: ignore[no-redef]
        """uvicorn's httptools protocol with the header bound."""


def protocol_for(http_impl: str) -> str:
    """uvicorn's ``http`` option for ``http_impl`` ('auto', 'httptools', 'h11'): the import
    string of the guarded class ('auto': httptools when installed, as uvicorn's own)."""
    if http_impl == "h11" or (http_impl == "auto" and GuardedHttpTools is None):
        return f"{__name__}:GuardedH11"
    if http_impl in ("auto", "httptools"):
        return f"{__name__}:GuardedHttpTools"
    return http_impl
