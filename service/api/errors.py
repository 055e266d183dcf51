"""Every error as RFC 9457 ``application/problem+json`` naming the field and the value."""

from __future__ import annotations

import logging
from typing import Any

import anyio
from fastapi import FastAPI, HTTPException, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.analysis.errors import ParameterError as AnalysisParameterError
from service.api.problems import ApiProblem, problem_from, wire_value
from service.recordings import RecordingError
from service.schemas.common import PROBLEM_MEDIA_TYPE
from sim.errors import ParameterError as SimParameterError

log = logging.getLogger("snapwarn.api")


def problem_response(problem: ApiProblem, instance: str | None) -> JSONResponse:
    return JSONResponse(
        problem.to_dict(instance),
        status_code=problem.status,
        media_type=PROBLEM_MEDIA_TYPE,
        headers=problem.headers or None,
    )


def _field_from_loc(loc: tuple[Any, ...]) -> str:
    parts = list(loc)
    if parts and parts[0] in ("body", "query", "path", "header", "form"):
        parts = parts[1:]
    out = ""
    for p in parts:
        if isinstance(p, int):
            out += f"[{p}]"
        else:
            out += ("." if out else "") + str(p)
    return out or "body"


async def _validation_handler(request: Request, exc: RequestValidationError) -> JSONResponse:
    errors = []
    for e in exc.errors():
        field = _field_from_loc(tuple(e.get("loc", ())))
        if e.get("type") == "json_invalid":
            field = "body"
        errors.append(
            {"field": field, "value": wire_value(e.get("input")), "message": e.get("msg", "")}
        )
    first = errors[:3]
    detail = "; ".join(f"{x['field']}: {x['value']!r} - {x['message']}" for x in first)
    if len(errors) > 3:
        detail += f"; and {len(errors) - 3} more"
    return problem_response(ApiProblem(422, detail, errors=errors), request.url.path)


async def _problem_handler(request: Request, exc: ApiProblem) -> JSONResponse:
    return problem_response(exc, request.url.path)


async def _data_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """Errors carrying their field as data (recordings, numerics): 413/415/422."""
    problem = problem_from(exc)
    if problem is None:  # pragma: no cover - registered only for the classes it maps
        return await _internal_handler(request, exc)
    return problem_response(problem, request.url.path)


async def _http_handler(request: Request, exc: StarletteHTTPException) -> JSONResponse:
    if isinstance(exc, BodyTooLarge):
        resp = problem_response(exc.problem, request.url.path)
        resp.headers["connection"] = "close"  # the rest of the body is left unread
        return resp
    detail = exc.detail if isinstance(exc.detail, str) else str(exc.detail)
    if exc.status_code == 404 and detail == "Not Found":
        detail = f"no resource at {request.url.path}"
    p = ApiProblem(exc.status_code, detail, headers=dict(exc.headers or {}))
    return problem_response(p, request.url.path)


async def _internal_handler(request: Request, exc: Exception) -> JSONResponse:
    import uuid

    cid = uuid.uuid4().hex[:12]
    log.exception("unhandled error on %s %s [correlation id %s]", request.method,
                  request.url.path, cid)
    p = ApiProblem(
        500,
        f"{type(exc).__name__}: the server failed; the error is logged under correlation id "
        f"{cid}",
        headers={"Connection": "close"},  # the request may not have been read to its end
    )
    resp = problem_response(p, request.url.path)
    return resp


def install_handlers(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _validation_handler)
    app.add_exception_handler(ApiProblem, _problem_handler)
    for cls in (RecordingError, SimParameterError, AnalysisParameterError):
        app.add_exception_handler(cls, _data_error_handler)
    app.add_exception_handler(StarletteHTTPException, _http_handler)
    app.add_exception_handler(Exception, _internal_handler)


class BodyTooLarge(HTTPException):
    """Raised while streaming an oversized body (FastAPI lets HTTPExceptions through)."""

    def __init__(self, problem: ApiProblem) -> None:
        super().__init__(problem.status, problem.detail)
        self.problem = problem


class BodyLimitMiddleware:
    """413 for bodies over ``max_bytes``: from Content-Length at once, else while streaming;
    408 (the connection closed) for a body whose next bytes take longer than
    ``read_timeout_s`` (a slow client holds no worker for ever)."""

    def __init__(self, app: ASGIApp, max_bytes: int, read_timeout_s: float = 30.0) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.read_timeout_s = read_timeout_s

    def _problem(self, size: Any) -> ApiProblem:
        return ApiProblem(
            413,
            f"request body of {size} bytes exceeds the limit of {self.max_bytes} bytes "
            "(setting SNAPWARN_MAX_BODY_BYTES)",
            field="body",
            value=size,
        )

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        for k, v in scope.get("headers", []):
            if k == b"content-length":
                try:
                    size = int(v)
                except ValueError:
                    size = -1
                if size > self.max_bytes:
                    resp = problem_response(self._problem(size), scope.get("path"))
                    resp.headers["connection"] = "close"  # the body is left unread
                    await _drain_and_send(resp, scope, receive, send)
                    return
        seen = 0
        done = scope["method"] in ("GET", "HEAD", "OPTIONS", "DELETE")

        async def limited() -> Message:
            nonlocal seen, done
            if done:  # the body was read: a wait for the disconnect is not bounded
                return await receive()
            try:
                with anyio.fail_after(self.read_timeout_s):
                    msg = await receive()
            except TimeoutError:
                raise BodyTooLarge(ApiProblem(
                    408, f"the request body did not arrive: no bytes for "
                    f"{self.read_timeout_s:g} s (setting SNAPWARN_BODY_READ_TIMEOUT_S)",
                    title="Request timeout", slug="request-timeout", field="body",
                    value=seen, headers={"Connection": "close"},
                )) from None  # fmt: skip
            if msg["type"] != "http.request" or not msg.get("more_body", False):
                done = True
            if msg["type"] == "http.request":
                seen += len(msg.get("body", b""))
                if seen > self.max_bytes:
                    raise BodyTooLarge(self._problem(f"more than {self.max_bytes}"))
            return msg

        await self.app(scope, limited, send)


async def _drain_and_send(resp: JSONResponse, scope: Scope, receive: Receive, send: Send) -> None:
    await resp(scope, receive, send)
