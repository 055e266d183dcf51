"""``Idempotency-Key`` on POSTs that create: a retry after an ambiguous failure (timeout,
dropped connection) gets the first answer again instead of creating a duplicate.

The first request with a key claims it (a pending record, unique per owner and key, held by a
random token under a lease renewed while it runs), runs, and stores its answer when it
succeeded (2xx); a failed first request releases the key. The work binds the resource it
creates to the claim in its own transaction (:func:`service.api.storage.idempotency.bind`), so
the two commit together. A retry with the same key and the same request (method, path, body:
SHA-256) gets the stored status and body with ``Idempotent-Replayed: true``; the same key on a
different request is a 422; while the first is still running (its lease held) a retry gets 409
with ``Retry-After``. A key whose request died (a kill -9) is recovered: when its work committed
the retry gets the resource (read by a GET of it) with the work's status; when it did not, the
retry takes the key over once the lease has run out and runs. The body is hashed as it streams
(never buffered).

A multipart body is fingerprinted by what it says, not by its bytes: HTTP clients pick a new
boundary for each request, so a retry of the same upload differs in its raw body. Its parts
(name, file name, content type and content, in order) are hashed as python-multipart's
streaming parser finds them (part headers bounded by the parser, contents hashed, never kept);
a body that does not parse as multipart (or has more than ``MAX_PARTS`` parts) falls back to
its raw bytes (a retry of it then has to be byte-identical).
"""

from __future__ import annotations

import hashlib
import json
import math
import uuid
from functools import partial
from typing import Any

import anyio
from anyio import to_thread
from starlette.requests import Request
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.api.auth import get_caller
from service.api.errors import problem_response
from service.api.problems import ApiProblem
from service.api.storage import IdempotencyRow
from service.api.storage.idempotency import CLAIM, Claim

try:  # python-multipart (Starlette's parser); named ``multipart`` before 0.0.13
    from python_multipart.multipart import MultipartParser, parse_options_header
except ImportError:  # pragma: no cover
    from multipart.multipart import MultipartParser, parse_options_header  # type: ignore

HEADER = "idempotency-key"
PENDING = 0  # status of a claimed key whose first request is still running
MAX_STORED = 1 << 20  # answers larger than this are not replayed (creation answers are small)
MAX_PARTS = 1000  # multipart bodies with more parts are fingerprinted by their raw bytes


def _problem(status: int, detail: str, value: Any) -> ApiProblem:
    return ApiProblem(status, detail, field="idempotency-key", value=value)


def _latin(b: bytes) -> str:
    """Bytes as sent, as text (reversibly)."""
    return b.decode("latin-1")


class Fingerprint:
    """SHA-256 of a request (method, path, body), fed with the body's chunks as they arrive.

    A JSON (or any non-multipart) body is hashed as its bytes. A ``multipart/form-data`` body
    with a boundary is hashed in a canonical form that does not depend on the boundary: each
    part's name, file name and content type (parameters sorted) and the SHA-256 of its
    content, in order. If it does not parse (or ends early), the raw bytes are used instead.
    """

    def __init__(self, method: str, path: str, content_type: str | None) -> None:
        head = f"{method} {path}\n".encode()
        self._raw = hashlib.sha256(head)
        self._parser: MultipartParser | None = None
        ctype, params = parse_options_header(content_type) if content_type else (b"", {})
        boundary = params.get(b"boundary")
        if ctype == b"multipart/form-data" and boundary:
            try:
                self._parser = MultipartParser(boundary, self._callbacks())
            except ValueError:  # a boundary python-multipart refuses (too long)
                self._parser = None
        self._canon = hashlib.sha256(head + b"multipart/form-data\n")
        self._part: Any = None  # the SHA-256 of the current part's content
        self._header: list[bytearray] = [bytearray(), bytearray()]
        self._headers: dict[bytes, bytes] = {}
        self._parts = 0
        self._ended = False

    # --- python-multipart callbacks (see MultipartParser) ---
    def _callbacks(self) -> dict[str, Any]:
        return {
            "on_part_begin": self._on_part_begin,
            "on_header_field": lambda d, a, b: self._header[0].extend(memoryview(d)[a:b]),
            "on_header_value": lambda d, a, b: self._header[1].extend(memoryview(d)[a:b]),
            "on_header_end": self._on_header_end,
            "on_part_data": lambda d, a, b: self._part.update(memoryview(d)[a:b]),
            "on_part_end": self._on_part_end,
            "on_end": self._on_end,
        }

    def _on_part_begin(self) -> None:
        if self._parts >= MAX_PARTS:  # no route takes that many (bounds the parsing time)
            raise ValueError("too many parts")
        self._part = hashlib.sha256()
        self._headers = {}

    def _on_header_end(self) -> None:
        name = bytes(self._header[0]).strip().lower()
        if name in (b"content-disposition", b"content-type"):
            self._headers[name] = bytes(self._header[1])
        self._header = [bytearray(), bytearray()]

    def _on_part_end(self) -> None:
        _, disp = parse_options_header(self._headers.get(b"content-disposition", b""))
        ctype, params = parse_options_header(self._headers.get(b"content-type", b""))
        record = [
            _latin(disp.get(b"name", b"")),
            None if b"filename" not in disp else _latin(disp[b"filename"]),
            _latin(ctype),
            sorted((_latin(k).lower(), _latin(v)) for k, v in params.items()),
            self._part.hexdigest() if self._part is not None else "",
        ]
        self._canon.update(json.dumps(record).encode() + b"\n")
        self._parts += 1
        self._part = None

    def _on_end(self) -> None:
        self._ended = True

    def update(self, chunk: bytes) -> None:
        """Feed the next piece of the body."""
        if not chunk:
            return
        self._raw.update(chunk)
        if self._parser is not None:
            try:
                self._parser.write(chunk)
            except ValueError:  # python-multipart's parse errors are ValueErrors
                self._parser = None

    def hexdigest(self) -> str:
        """The fingerprint of the whole body fed so far."""
        if self._parser is not None and self._ended and self._parts:
            return self._canon.hexdigest()
        return self._raw.hexdigest()


class IdempotencyMiddleware:
    """See the module docstring; applies to POST under /v1 with an ``Idempotency-Key``."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "POST":
            await self.app(scope, receive, send)
            return
        key = None
        for k, v in scope["headers"]:
            if k == b"idempotency-key":
                key = v.decode("latin-1")
        state = getattr(scope["app"].state, "snapwarn", None)
        if key is None or state is None or not scope["path"].startswith("/v1/"):
            await self.app(scope, receive, send)
            return
        try:
            if not 1 <= len(key) <= 200 or not key.isprintable():
                raise _problem(422, "Idempotency-Key must be 1 to 200 printable characters", key)
            caller = await get_caller(Request(scope))
        except ApiProblem as p:
            await _answer(p, scope, receive, send)
            return
        lease = float(getattr(state.settings, "idempotency_lease_s", 10.0))
        await self._run(scope, receive, send, state.store, caller.owner, key, lease)

    async def _run(
        self, scope: Scope, receive: Receive, send: Send, store: Any, owner: str, key: str,
        lease: float,
    ) -> None:  # fmt: skip
        ctype = None
        for k, v in scope["headers"]:
            if k == b"content-type":
                ctype = v.decode("latin-1")
        digest = Fingerprint(scope["method"], scope["path"], ctype)
        token = uuid.uuid4().hex
        first = await to_thread.run_sync(store.get_idempotent, owner, key)
        for _ in range(3):
            if first is None:
                if await to_thread.run_sync(store.claim_idempotent, owner, key, token, lease):
                    break
            elif _dead(first):  # its request died before its work committed: take it over
                take = partial(store.take_over_idempotent, owner, key, first, token, lease)
                if await to_thread.run_sync(take):
                    first = None
                    break
            else:
                break
            first = await to_thread.run_sync(store.get_idempotent, owner, key)
        if first is not None:  # a retry: read (hash) the body, then replay or refuse
            while True:
                msg = await receive()
                digest.update(msg.get("body", b""))
                if not msg.get("more_body"):
                    break
            await self._replay(first, digest.hexdigest(), scope, receive, send, store, owner)
            return
        await self._first(scope, receive, send, store, owner, key, token, lease, digest)

    async def _first(
        self, scope: Scope, receive: Receive, send: Send, store: Any, owner: str, key: str,
        token: str, lease: float, digest: Fingerprint,
    ) -> None:  # fmt: skip
        """Run the request that holds the key (its lease renewed meanwhile); store its answer
        (a success) or release the key."""

        async def hashing() -> Message:
            msg = await receive()
            if msg["type"] == "http.request":
                digest.update(msg.get("body", b""))
            return msg

        status = [500]
        chunks: list[bytes] = []
        size = [0]
        settled = [False]

        async def settle(ok: bool) -> None:
            """Store the answer (a success) or release the key (anything else), once."""
            if settled[0]:
                return
            settled[0] = True
            if ok:
                try:
                    body = json.loads(b"".join(chunks) or b"null")
                except ValueError:
                    body = None
                try:
                    await to_thread.run_sync(
                        store.complete_idempotent, owner, key, digest.hexdigest(), status[0],
                        body, token,
                    )  # fmt: skip
                except Exception:
                    await to_thread.run_sync(store.release_idempotent, owner, key, token)
                    raise
            else:
                await to_thread.run_sync(store.release_idempotent, owner, key, token)

        async def capture(msg: Message) -> None:
            if msg["type"] == "http.response.start":
                status[0] = msg["status"]
            elif msg["type"] == "http.response.body":
                size[0] += len(msg.get("body", b""))
                if size[0] <= MAX_STORED:
                    chunks.append(msg.get("body", b""))
                if not msg.get("more_body", False):
                    # settled before the answer's end leaves: a client that retries as soon as
                    # it has the answer finds the key stored (or free), not still running (409)
                    await settle(200 <= status[0] < 300 and size[0] <= MAX_STORED)
            await send(msg)

        async def renew() -> None:
            while True:
                await anyio.sleep(lease / 3.0)
                try:
                    await to_thread.run_sync(store.renew_idempotent, owner, key, token, lease)
                except Exception:  # noqa: BLE001 - a database hiccup: the next renewal tries
                    pass

        claim = CLAIM.set(Claim(owner, key, token, scope["path"], digest.hexdigest))
        try:
            async with anyio.create_task_group() as tg:
                tg.start_soon(renew)
                try:
                    await self.app(scope, hashing, capture)
                finally:
                    tg.cancel_scope.cancel()
        finally:
            CLAIM.reset(claim)
            with anyio.CancelScope(shield=True):
                await settle(False)  # no complete answer was sent (an error): the key is free

    async def _replay(
        self, first: IdempotencyRow, fingerprint: str, scope: Scope, receive: Receive,
        send: Send, store: Any, owner: str,
    ) -> None:  # fmt: skip
        key = first.key
        if first.status == PENDING and first.resource and first.fingerprint in ("", fingerprint):
            # its work committed (the request may have died before its answer): the resource
            recovered = await self._recover(first, scope, store, owner, fingerprint)
            if recovered is not None:
                first = recovered
        if first.status == PENDING and first.resource and first.fingerprint != fingerprint:
            first.status = -1  # a different request: the 422 below
        if first.status == PENDING:
            left = _lease_left(first)
            problem = _problem(409, "a request with this Idempotency-Key is running; retry "
                               f"in {left} s", key)  # fmt: skip
            problem.headers = {**(problem.headers or {}), "Retry-After": str(left)}
            await _answer(problem, scope, receive, send)
        elif first.fingerprint != fingerprint:
            problem = _problem(
                422,
                "this Idempotency-Key was used for a different request (method, path or "
                "body differ); use a new key",
                key,
            )
            await _answer(problem, scope, receive, send)
        else:
            from fastapi.responses import JSONResponse

            headers = {"Idempotent-Replayed": "true"}
            if isinstance(first.body, dict) and first.body.get("id"):
                headers["Location"] = f"{scope['path'].rstrip('/')}/{first.body['id']}"
            resp = JSONResponse(first.body, status_code=first.status, headers=headers)
            await resp(scope, receive, send)

    async def _recover(
        self, first: IdempotencyRow, scope: Scope, store: Any, owner: str, fingerprint: str
    ) -> IdempotencyRow | None:
        """The answer of a key whose work committed, read by a GET of its resource (with the
        retry's own credentials), stored as the key's answer; None when it cannot be read."""
        got: dict[str, Any] = {"status": 0, "body": []}

        async def empty() -> Message:
            return {"type": "http.request", "body": b"", "more_body": False}

        async def keep(msg: Message) -> None:
            if msg["type"] == "http.response.start":
                got["status"] = msg["status"]
            elif msg["type"] == "http.response.body":
                got["body"].append(msg.get("body", b""))

        path = str(first.resource)
        drop = (b"content-type", b"content-length", b"idempotency-key")
        headers = [(k, v) for k, v in scope["headers"] if k not in drop]
        sub = {**scope, "method": "GET", "path": path, "raw_path": path.encode(),
               "query_string": b"", "headers": headers}  # fmt: skip
        await self.app(sub, empty, keep)
        if got["status"] not in (200, 404):  # 404: the work's resource was deleted since
            return None
        try:
            body = json.loads(b"".join(got["body"]) or b"null")
        except ValueError:
            return None
        status = int(first.resource_status or 200) if got["status"] == 200 else 404
        complete = partial(store.complete_idempotent, owner, first.key, fingerprint, status, body)
        await to_thread.run_sync(complete)
        return await to_thread.run_sync(store.get_idempotent, owner, first.key)


def _dead(row: IdempotencyRow) -> bool:
    """A pending key whose lease ran out and whose work did not commit (its request died)."""
    from service.api.storage.models import utcnow

    return (
        row.status == PENDING
        and not row.resource
        and (row.lease_until is None or row.lease_until < utcnow())
    )


def _lease_left(row: IdempotencyRow) -> int:
    """Whole seconds (at least 1) until a pending key's lease runs out."""
    from service.api.storage.models import utcnow

    if row.lease_until is None:
        return 1
    return max(1, math.ceil((row.lease_until - utcnow()).total_seconds()))


async def _answer(problem: ApiProblem, scope: Scope, receive: Receive, send: Send) -> None:
    await problem_response(problem, scope.get("path"))(scope, receive, send)
