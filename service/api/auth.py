"""Who is calling: API keys, the caller's identity (``Caller``) and the ``CallerDep`` dependency.

Keys (``snapwarn keys create``) are stored as SHA-256 digests and compared in constant time.
They are required on /v1 when the server listens beyond loopback (``SNAPWARN_AUTH=auto``, the
default), always with ``SNAPWARN_AUTH=on``, never with ``SNAPWARN_AUTH=off`` (explicit opt-out).
Without a key on a loopback server every request is ``Caller(owner="local", admin=True)``; a
key that is sent is always checked (so owners stay apart on loopback too). That trust is the
socket peer's: a request that carries forwarding headers (``Forwarded``, ``X-Forwarded-*``,
``X-Real-IP``: it came through a reverse proxy, whatever its ``Host``) or whose peer is not a
loopback address needs a key, unless keys are turned off (``SNAPWARN_AUTH=off``).

Every resource row carries the ``owner`` that created it; a caller reads its own rows only (an
admin reads all): anything else answers 404, as if the resource did not exist.
"""

from __future__ import annotations

import functools
import hmac
import ipaddress
import time
from dataclasses import dataclass
from typing import Annotated

from anyio import to_thread
from fastapi import Depends, Request

from service.api.problems import ApiProblem
from service.api.settings import Settings

LOCAL_OWNER = "local"
ENV_KEY_OWNER = "admin"
_CACHE_S = 2.0  # a revoked key stops working within this time


@dataclass(frozen=True)
class Caller:
    """The identity a request acts as.

    Attributes
    ----------
    owner : str
        The owner name stored on every row the request creates.
    admin : bool
        Sees and manages every owner's resources.
    key_id : str or None
        The id of the key used (None for the loopback default and the env key).
    """

    owner: str
    admin: bool
    key_id: str | None = None

    def sees(self, owner: str | None) -> bool:
        """True if this caller may read a resource of ``owner``."""
        return self.admin or owner == self.owner

    @property
    def scope(self) -> str | None:
        """The owner a listing is restricted to (None: all owners, for an admin)."""
        return None if self.admin else self.owner


LOCAL_CALLER = Caller(owner=LOCAL_OWNER, admin=True)


def is_loopback(host: str | None) -> bool:
    """True for 127.0.0.0/8, ::1 and ``localhost``; False for 0.0.0.0, :: and other names."""
    if not host:
        return False
    return _is_loopback(host.strip("[]"))


@functools.lru_cache(maxsize=1024)
def _is_loopback(h: str) -> bool:
    """``is_loopback`` of a bare name (memoised: asked on every request)."""
    if h == "localhost":
        return True
    try:
        return ipaddress.ip_address(h).is_loopback
    except ValueError:
        return False


def _server_host(request: Request) -> str | None:
    server = request.scope.get("server")
    return server[0] if server else None


def keys_required(settings: Settings, request: Request | None = None) -> bool:
    """Whether /v1 needs a key for this server (and this request's listening address)."""
    if settings.auth == "off":
        return False
    if settings.auth == "on" or settings.api_key:
        return True
    if not is_loopback(settings.host):
        return True
    if request is not None:  # the socket's own address, when it is an IP beyond loopback
        host = _server_host(request)
        if host is not None and _beyond_loopback(host.strip("[]")):
            return True
    return False


@functools.lru_cache(maxsize=1024)
def _beyond_loopback(h: str) -> bool:
    """True for an IP address that is not a loopback one (False for names; memoised)."""
    try:
        return not ipaddress.ip_address(h).is_loopback
    except ValueError:
        return False


#: Headers a reverse proxy adds: a request carrying one came from elsewhere.
FORWARDING_HEADERS = (
    b"forwarded", b"x-forwarded-for", b"x-forwarded-host", b"x-forwarded-proto",
    b"x-forwarded-port", b"x-real-ip", b"x-client-ip", b"true-client-ip", b"via",
)  # fmt: skip


def proxied(request: Request) -> bool:
    """True when the request did not come straight from a loopback peer: forwarding headers
    (a reverse proxy on this machine forwards from anywhere) or a socket peer beyond
    loopback (an in-process client names no IP: it passes)."""
    for k, _ in request.scope.get("headers", ()):
        if k in FORWARDING_HEADERS:
            return True
    client = request.scope.get("client")
    return bool(client) and _beyond_loopback(str(client[0]).strip("[]"))


def _token(request: Request) -> str | None:
    auth = request.headers.get("authorization", "")
    if auth[:7].lower() == "bearer ":
        return auth[7:].strip() or None
    return request.headers.get("x-api-key") or None


def _unauthorized(given: bool) -> ApiProblem:
    return ApiProblem(
        401,
        "wrong or revoked API key"
        if given
        else "an API key is required (send "
        "'Authorization: Bearer <key>'; create one with 'snapwarn keys create')",
        field="authorization",
        value="<hidden>" if given else None,
        headers={"WWW-Authenticate": "Bearer"},
    )


async def get_caller(request: Request) -> Caller:
    """The caller of ``request`` (401 when a key is needed and missing, wrong or revoked)."""
    st = getattr(request.app.state, "snapwarn", None)
    settings: Settings = st.settings if st else request.app.state.settings
    token = _token(request)
    if token is None:
        if keys_required(settings, request) or (settings.auth != "off" and proxied(request)):
            raise _unauthorized(False)
        return LOCAL_CALLER
    if settings.api_key and hmac.compare_digest(
        token.encode("utf-8", "surrogatepass"), settings.api_key.encode("utf-8", "surrogatepass")
    ):
        return Caller(owner=ENV_KEY_OWNER, admin=True)
    if st is None:
        raise ApiProblem(503, "the service is not started (lifespan did not run)")
    cache: dict[str, tuple[float, Caller | None]] = st.extra.setdefault("key_cache", {})
    now = time.monotonic()
    hit = cache.get(token)
    if hit is not None and now - hit[0] < _CACHE_S:
        caller = hit[1]
    else:
        info = await to_thread.run_sync(st.store.verify_key, token)
        caller = Caller(owner=info.owner, admin=info.admin, key_id=info.id) if info else None
        if len(cache) > 10_000:
            cache.clear()
        cache[token] = (now, caller)
    if caller is None:
        raise _unauthorized(True)
    return caller


CallerDep = Annotated[Caller, Depends(get_caller)]
"""Route parameter ``caller: CallerDep``: the identity to store as ``owner`` and to filter by."""
