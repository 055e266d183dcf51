"""``Idempotency-Key`` on POSTs that create: a retry after an ambiguous failure (timeout,
dropped connection) gets the first answer again instead of creating a duplicate.

The first request with a key claims it (a pending record, unique per owner and key), runs, and
stores its answer when it succeeded (2xx); a failed first request releases the key. A retry
with the same key and the same request (method, path, body: SHA-256) gets the stored status and
body with ``Idempotent-Replayed: true``; the same key on a different request is a 422; while the
first is still running a retry gets 409. The body is hashed as it streams (never buffered).
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

HEADER = "idempotency-key"
PENDING = 0  # status of a claimed key whose first request is still running
MAX_STORED = 1 << 20  # answers larger than this are not replayed (creation answers are small)


def _problem(status: int, detail: str, value: Any) -> ApiProblem:
    return ApiProblem(status, detail, field="idempotency-key", value=value)


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
        digest = hashlib.sha256(f"{scope['method']} {scope['path']}\n".encode())
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

        async def capture(msg: Message) -> None:
            if msg["type"] == "http.response.start":
                status[0] = msg["status"]
            elif msg["type"] == "http.response.body":
                size[0] += len(msg.get("body", b""))
                if size[0] <= MAX_STORED:
                    chunks.append(msg.get("body", b""))
            await send(msg)

        ok = False
        try:
            await self.app(scope, hashing, capture)
            ok = 200 <= status[0] < 300 and size[0] <= MAX_STORED
        finally:
            if ok:
                try:
                    body = json.loads(b"".join(chunks) or b"null")
                except ValueError:
                    body = None
                await to_thread.run_sync(
                    store.complete_idempotent, owner, key, digest.hexdigest(), status[0], body
                )
            else:
                await to_thread.run_sync(store.release_idempotent, owner, key)

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
