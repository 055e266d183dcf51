"""``Idempotency-Key`` on POSTs that create: a retry after an ambiguous failure (timeout,
dropped connection) gets the first answer again instead of creating a duplicate.

The first request with a key claims it (a pending record, unique per owner and key), runs, and
stores its answer when it succeeded (2xx); a failed first request releases the key. A retry
with the same key and the same request (method, path, body: SHA-256) gets the stored status and
body with ``Idempotent-Replayed: true``; the same key on a different request is a 422; while the
first is still running a retry gets 409. The body is hashed as it streams (never buffered).

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
from typing import Any

from anyio import to_thread
from starlette.requests import Request
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.api.auth import get_caller
from service.api.errors import problem_response
from service.api.problems import ApiProblem
from service.api.storage import IdempotencyRow

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
        await self._run(scope, receive, send, state.store, caller.owner, key)

    async def _run(
        self, scope: Scope, receive: Receive, send: Send, store: Any, owner: str, key: str
    ) -> None:
        ctype = None
        for k, v in scope["headers"]:
            if k == b"content-type":
                ctype = v.decode("latin-1")
        digest = Fingerprint(scope["method"], scope["path"], ctype)
        first = await to_thread.run_sync(store.get_idempotent, owner, key)
        if first is None and not await to_thread.run_sync(store.claim_idempotent, owner, key):
            first = await to_thread.run_sync(store.get_idempotent, owner, key)
        if first is not None:  # a retry: read (hash) the body, then replay or refuse
            while True:
                msg = await receive()
                digest.update(msg.get("body", b""))
                if not msg.get("more_body"):
                    break
            await self._replay(first, digest.hexdigest(), scope, receive, send)
            return

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
                        store.complete_idempotent, owner, key, digest.hexdigest(), status[0], body
                    )
                except Exception:
                    await to_thread.run_sync(store.release_idempotent, owner, key)
                    raise
            else:
                await to_thread.run_sync(store.release_idempotent, owner, key)

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

        try:
            await self.app(scope, hashing, capture)
        finally:
            await settle(False)  # no complete answer was sent (an error): the key is free

    async def _replay(
        self, first: IdempotencyRow, fingerprint: str, scope: Scope, receive: Receive, send: Send
    ) -> None:
        key = first.key
        if first.status == PENDING:
            problem = _problem(409, "a request with this Idempotency-Key is running", key)
            await _answer(problem, scope, receive, send)
        elif first.fingerprint != fingerprint:
            problem = _problem(
                422, "this Idempotency-Key was used for a different request (method, path or "
                "body differ); use a new key", key
            )
            await _answer(problem, scope, receive, send)
        else:
            from fastapi.responses import JSONResponse

            headers = {"Idempotent-Replayed": "true"}
            if isinstance(first.body, dict) and first.body.get("id"):
                headers["Location"] = f"{scope['path'].rstrip('/')}/{first.body['id']}"
            resp = JSONResponse(first.body, status_code=first.status, headers=headers)
            await resp(scope, receive, send)


async def _answer(problem: ApiProblem, scope: Scope, receive: Receive, send: Send) -> None:
    await problem_response(problem, scope.get("path"))(scope, receive, send)
