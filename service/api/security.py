"""Browser-facing defences: cross-site requests, DNS rebinding, CORS (closed by default).

A browser may send "simple" cross-site requests (``text/plain``, form or multipart POSTs)
without a CORS preflight; the server must refuse them itself:

- a state-changing request (POST, PUT, PATCH, DELETE) whose ``Origin`` is neither this server
  (the ``Host`` it was sent to) nor one of ``SNAPWARN_CORS_ORIGINS`` is refused (403), and so is
  one marked ``Sec-Fetch-Site: cross-site`` by the browser;
- request bodies on /v1 must be JSON or multipart (``text/plain`` and url-encoded forms: 415);
- DNS rebinding: on a loopback server that needs no key, every request must name a loopback
  ``Host`` (``localhost``, ``127.0.0.1``, ``[::1]``, any port) or one of
  ``SNAPWARN_ALLOWED_HOSTS`` (403 naming ``host``): a page of ``evil.example`` whose name
  was rebound to 127.0.0.1 sends ``Host: evil.example``, with or without ``Origin`` and
  ``Sec-Fetch-*`` (older browsers send neither on a GET). A request without ``Host`` (HTTP/1.0,
  never a browser) passes. On a keyless server beyond loopback (``SNAPWARN_AUTH=off``) only
  browser requests (``Origin`` or ``Sec-Fetch-*``) are held to this; a server that needs keys
  (``SNAPWARN_AUTH=on``, ``SNAPWARN_API_KEY``, or listening beyond loopback), e.g. behind a
  reverse proxy (``SNAPWARN_FORWARDED_ALLOW_IPS``) under a public name, takes any ``Host``.
  In-process clients (Starlette's ``TestClient``, httpx's ``ASGITransport``) have no socket:
  their ASGI ``server`` is the URL's own name (``testserver``), which their ``Host`` names and
  which is accepted; a real server (uvicorn) reports its socket's IP address there instead,
  so no ``Host`` a browser sends can match it.

CORS answers are added only for the configured origins (Starlette's ``CORSMiddleware``).

Every answer carries ``Content-Security-Policy`` (scripts, styles, images and connections from
this server only, no framing, no plugins; ``/docs`` also runs Swagger UI's inline start-up
script), ``X-Frame-Options: DENY``, ``X-Content-Type-Options: nosniff`` and
``Referrer-Policy: same-origin`` (not ``no-referrer``: under it a browser sends
``Origin: null`` on the pages' own form posts, which the cross-site check refuses).
"""

from __future__ import annotations

import ipaddress
import logging
import re
from urllib.parse import urlsplit

import anyio
from starlette.requests import Request
from starlette.types import ASGIApp, Receive, Scope, Send

from service.api.auth import is_loopback, keys_required
from service.api.errors import problem_response
from service.api.problems import ApiProblem
from service.api.settings import Settings

UNSAFE = frozenset({"POST", "PUT", "PATCH", "DELETE"})
_CSP = ("default-src 'self'; script-src 'self'{extra}; style-src 'self' 'unsafe-inline'; "
        "img-src 'self' data:; connect-src 'self'; object-src 'none'; base-uri 'self'; "
        "form-action 'self'; frame-ancestors 'none'")  # fmt: skip
SECURITY_HEADERS = [
    (b"content-security-policy", _CSP.format(extra="").encode()),
    (b"x-frame-options", b"DENY"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"same-origin"),
]
_DOCS_HEADERS = [(b"content-security-policy", _CSP.format(extra=" 'unsafe-inline'").encode()),
                 *SECURITY_HEADERS[1:]]  # fmt: skip
BODY_TYPES = ("application/json", "multipart/form-data", "application/merge-patch+json")


def _host_of(value: str) -> str:
    """The host name of a ``Host`` header value (port and brackets removed)."""
    v = value.strip().lower()
    if v.startswith("["):
        return v[1:].split("]", 1)[0]
    v = v.rsplit(":", 1)[0] if v.count(":") == 1 else v
    return v[:-1] if v.endswith(".") else v  # "localhost." is "localhost"


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def _origin_key(origin: str) -> str:
    """``scheme://host[:port]`` of an origin, lower-cased (default ports dropped)."""
    u = urlsplit(origin.strip().lower())
    port = u.port
    default = {"http": 80, "https": 443}.get(u.scheme)
    host = u.hostname or ""
    if ":" in host:
        host = f"[{host}]"
    return f"{u.scheme}://{host}" + (f":{port}" if port and port != default else "")


class SecurityMiddleware:
    """Refuse cross-site and rebinding requests before any route runs (see the module)."""

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app = app
        self.settings = settings
        self.allowed = {_origin_key(o) for o in settings.cors_origins if o != "*"}
        self.any_origin = "*" in settings.cors_origins
        self.allowed_hosts = {_host_of(h) for h in settings.allowed_hosts if h.strip()}
        self.loopback_bound = is_loopback(settings.host)

    def _host_ok(self, host: str, scope: Scope) -> bool:
        """Whether ``host`` names this keyless server (see the module's DNS rebinding)."""
        name = _host_of(host)
        if is_loopback(name) or name in self.allowed_hosts:
            return True
        server = scope.get("server")  # an in-process client's own name (no socket)
        own = str(server[0]).lower() if server else None
        return bool(own) and name == own and not _is_ip(own)

    def _check(self, scope: Scope) -> ApiProblem | None:
        headers = {k.decode("latin-1"): v.decode("latin-1") for k, v in scope["headers"]}
        method = scope["method"]
        origin = headers.get("origin")
        host = headers.get("host", "")
        fetch_site = headers.get("sec-fetch-site")
        browser = origin is not None or fetch_site is not None
        if method in UNSAFE:
            if origin is not None and origin != "null":
                key = _origin_key(origin)
                scheme = scope.get("scheme", "http")
                same = key in (_origin_key(f"{scheme}://{host}"), _origin_key(f"http://{host}"),
                               _origin_key(f"https://{host}"))
                if not (same or self.any_origin or key in self.allowed):
                    return _cross_site("origin", origin)
            elif origin == "null":
                return _cross_site("origin", origin)
            elif fetch_site == "cross-site" and not self.any_origin:
                return _cross_site("sec-fetch-site", fetch_site)
            if scope["path"].startswith("/v1/"):
                ctype = headers.get("content-type", "").split(";", 1)[0].strip().lower()
                if ctype and ctype not in BODY_TYPES:
                    return ApiProblem(
                        415,
                        f"send application/json or multipart/form-data, not {ctype!r}",
                        field="content-type",
                        value=ctype,
                    )
        if (
            "host" in headers
            and (browser or self.loopback_bound)
            and not self._host_ok(host, scope)
            and not keys_required(self.settings, Request(scope))
        ):
            return ApiProblem(
                403,
                f"Host {host!r} is not this keyless loopback server's (DNS rebinding?): name "
                "localhost, 127.0.0.1 or [::1] (setting SNAPWARN_ALLOWED_HOSTS adds names)",
                title="Forbidden",
                slug="forbidden",
                field="host",
                value=host,
            )
        return _nul_check(scope)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        extra = _DOCS_HEADERS if scope.get("path") == "/docs" else SECURITY_HEADERS

        async def with_headers(msg: dict) -> None:
            if msg["type"] == "http.response.start":
                have = {k.lower() for k, _ in msg.get("headers", ())}
                msg["headers"] = [*msg.get("headers", ()),
                                  *((k, v) for k, v in extra if k not in have)]  # fmt: skip
            await send(msg)

        problem = self._check(scope)
        if problem is not None:
            resp = problem_response(problem, scope.get("path"))
            resp.headers["connection"] = "close"  # the body was not read
            await resp(scope, receive, with_headers)
            return
        if scope["method"] in UNSAFE and _is_json(scope):
            timeout = float(getattr(self.settings, "body_read_timeout_s", 30.0))
            receive, problem = await _small_nul_check(scope, receive, timeout)
            if problem is not None:
                resp = problem_response(problem, scope.get("path"))
                await resp(scope, receive, with_headers)
                return
        await self.app(scope, receive, with_headers)


def _is_json(scope: Scope) -> bool:
    for k, v in scope["headers"]:
        if k == b"content-type":
            return b"json" in v.lower()
    return False


_NUL_ESCAPE = re.compile(rb"(\\+)u0000", re.IGNORECASE)
_KEY_BEFORE = re.compile(rb'"([^"\\]{1,100})"\s*:\s*[\[{"]?[^:]*$')


#: JSON bodies up to this size (64 KiB: requests other than samples) are read whole and checked
#: before the app sees them (the 422
#: names the field); larger ones are checked as they stream (an error while parsing).
_WHOLE = 1 << 16


async def _small_nul_check(
    scope: Scope, receive: Receive, timeout: float = 30.0
) -> tuple[Receive, ApiProblem | None]:
    """A small JSON body read and checked for NUL characters (see :func:`_no_nul`), replayed
    to the app; a larger one checked as it streams. A body whose bytes stop coming for
    ``timeout`` seconds is a 408."""
    length = None
    for k, v in scope["headers"]:
        if k == b"content-length":
            try:
                length = int(v)
            except ValueError:
                length = None
    if length is None or length > _WHOLE:
        return _no_nul(receive), None
    parts, more = [], True
    while more:
        try:
            with anyio.fail_after(timeout):
                msg = await receive()
        except TimeoutError:
            late = ApiProblem(408, f"the request body did not arrive: no bytes for {timeout:g} s "
                              "(setting SNAPWARN_BODY_READ_TIMEOUT_S)", title="Request timeout",
                              slug="request-timeout", field="body", value=None,
                              headers={"Connection": "close"})  # fmt: skip
            return _replay([{"type": "http.disconnect"}]), late
        if msg["type"] != "http.request":
            return _replay([msg]), None
        parts.append(msg.get("body", b""))
        more = msg.get("more_body", False)
    body = b"".join(parts)
    checked = _no_nul(_replay([{"type": "http.request", "body": body, "more_body": False}]))
    try:
        await checked()
    except ApiProblem as p:
        return _replay([{"type": "http.request", "body": b"", "more_body": False}]), p
    return _replay([{"type": "http.request", "body": body, "more_body": False}], receive), None


def _replay(msgs: list[dict], then: Receive | None = None) -> Receive:
    """``receive`` that gives ``msgs`` first, then ``then`` (a disconnect wait)."""
    queue = list(msgs)

    async def wrapped() -> dict:
        if queue:
            return queue.pop(0)
        if then is not None:
            return await then()
        return {"type": "http.disconnect"}

    return wrapped


def _no_nul(receive: Receive) -> Receive:
    """``receive`` that refuses a JSON body holding a NUL character (``\\u0000`` in a string:
    no database text column can store it; silently dropping it would change a name): a 422
    naming the nearest key before it."""
    tail = [b""]

    async def wrapped() -> dict:
        msg = await receive()
        chunk = msg.get("body", b"")
        if chunk and (b"u0000" in chunk or b"U0000" in chunk or tail[0]):
            text = tail[0] + chunk
            for m in _NUL_ESCAPE.finditer(text):
                if len(m.group(1)) % 2 == 1:  # an escape, not an escaped backslash
                    key = _KEY_BEFORE.search(text[max(0, m.start() - 300) : m.start()])
                    field = key.group(1).decode("utf-8", "replace") if key else "body"
                    raise ApiProblem(422, f"{field}: a NUL character (\\u0000) is not allowed "
                                     "in a text", field=field, value=None)  # fmt: skip
            tail[0] = text[-16:]
        return msg

    return wrapped


def _cross_site(field: str, value: str) -> ApiProblem:
    return ApiProblem(
        403,
        f"cross-site request refused ({field} {value!r} is not this server nor an allowed "
        "origin; setting SNAPWARN_CORS_ORIGINS)",
        title="Forbidden",
        slug="cross-site",
        field=field,
        value=value,
    )


def _nul_check(scope: Scope) -> ApiProblem | None:
    """422 for a NUL character in the path or the query (no database column can hold it)."""
    if "\x00" in scope.get("path", ""):
        return ApiProblem(422, "the path holds a NUL character", field="path", value=None)
    query = scope.get("query_string", b"")
    if b"%00" in query or b"\x00" in query:
        from urllib.parse import parse_qsl

        for name, value in parse_qsl(query.decode("latin-1"), keep_blank_values=True):
            if "\x00" in name or "\x00" in value:
                return ApiProblem(
                    422,
                    f"{name.replace(chr(0), '?')}: a NUL character is not allowed",
                    field=name.replace("\x00", "?"),
                    value=value.replace("\x00", "\\0"),
                )
    return None


#: Query parameters whose values never reach a log (an API key sent in a URL, a token).
SECRET_PARAMS = re.compile(
    r"(?i)([?&](?:key|api_key|apikey|api-key|token|access_token|secret|password|auth)=)[^&\s]*"
)


class RedactSecrets(logging.Filter):
    """Masks secret query values in the access log's request line (``?key=...`` -> ``***``)."""

    def filter(self, record: logging.LogRecord) -> bool:
        args = record.args
        if isinstance(args, tuple) and args:
            record.args = tuple(
                SECRET_PARAMS.sub(r"\1***", a) if isinstance(a, str) and "=" in a else a
                for a in args
            )
        elif isinstance(record.msg, str) and "=" in record.msg:
            record.msg = SECRET_PARAMS.sub(r"\1***", record.msg)
        return True


def redact_logs() -> None:
    """Install :class:`RedactSecrets` on uvicorn's access and error logs (once)."""
    for name in ("uvicorn.access", "uvicorn.error", "snapwarn"):
        lg = logging.getLogger(name)
        if not any(isinstance(f, RedactSecrets) for f in lg.filters):
            lg.addFilter(RedactSecrets())
