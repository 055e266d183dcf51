"""The hot path's door: ``POST /v1/detections`` with a small inline body, answered without the
framework's routing.

The request's work runs whole in an analysis worker (:func:`routers.detections.inline_detection`:
parse, validate, detect, serialise); what the event loop then does per request was mostly the
framework's own layers (routing, dependency resolution, the exception, exit-stack and body-limit
wrappers around every message): 0.59 -> 0.42 ms of its CPU per request at 32 clients
(bench/service.py). This middleware sits inside the security, body-limit and idempotency
middlewares, so their checks still apply; it checks the caller as the route does, hands the
body to the same worker function as the route, and writes the same document. An error (a
validation error, a limit, an error of the numerics) is answered by the app's own exception
handlers, as the route's would be; a body naming a stored signal goes on to the route.
A test compares every kind of answer with the route's.
"""

from __future__ import annotations

from typing import Any

from fastapi.exceptions import RequestValidationError
from starlette.requests import Request
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.api import limits
from service.api.auth import get_caller
from service.api.routers.detections import inline_detection

_PATH = "/v1/detections"


class HotPathMiddleware:
    """See the module docstring."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    @staticmethod
    def _eligible(scope: Scope) -> bool:
        """A POST to the route with a declared JSON body small enough to be parsed whole."""
        if scope["type"] != "http" or scope["method"] != "POST" or scope["path"] != _PATH:
            return False
        state = getattr(scope["app"].state, "snapwarn", None)
        if state is None:
            return False
        size = None
        for k, v in scope["headers"]:
            if k == b"content-length":
                size = int(v) if v.isdigit() else None
            elif k == b"content-type" and not v.lower().startswith(b"application/json"):
                return False
            elif k == b"transfer-encoding":
                return False
        return size is not None and size <= state.settings.json_stream_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if not self._eligible(scope):
            await self.app(scope, receive, send)
            return
        state = scope["app"].state.snapwarn
        s = state.settings
        try:
            await get_caller(Request(scope))
            body = await _read(receive)
            if body is None:
                return  # the client went away
            limits.check_json_samples(body, s.max_samples)
            kind, out = await state.run(inline_detection, body, s.max_samples, s.uniform_rtol)
            if kind == "invalid":
                raise RequestValidationError(out)
        except Exception as exc:
            handler = _handler(scope["app"], exc)
            if handler is None:
                raise  # as from the route: the server-error middleware answers and logs it
            response = await handler(Request(scope), exc)
            await response(scope, receive, send)
            return
        if kind != "json":  # it names a stored signal: the route reads it
            await self.app(scope, _replay(body), send)
            return
        await send(
            {
                "type": "http.response.start",
                "status": 200,
                "headers": [
                    (b"content-length", str(len(out)).encode()),
                    (b"content-type", b"application/json"),
                ],
            }
        )
        await send({"type": "http.response.body", "body": out})
        state.extra["hot_path_answers"] = state.extra.get("hot_path_answers", 0) + 1


async def _read(receive: Receive) -> bytes | None:
    """The whole body; None when the client disconnects first."""
    chunks: list[bytes] = []
    while True:
        msg = await receive()
        if msg["type"] != "http.request":
            return None
        chunks.append(msg.get("body", b""))
        if not msg.get("more_body", False):
            return b"".join(chunks)


def _handler(app: Any, exc: Exception) -> Any:
    """The app's handler of ``exc``'s class (by its MRO, as Starlette looks it up), except the
    catch-all ``Exception`` one, which the server-error middleware applies."""
    handlers = app.exception_handlers
    for cls in type(exc).__mro__:
        if cls is Exception:
            return None
        if cls in handlers:
            return handlers[cls]
    return None


def _replay(body: bytes) -> Receive:
    """A ``receive`` that gives ``body`` once, then waits as a finished request does."""
    sent = False

    async def receive() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return {"type": "http.disconnect"}

    return receive
