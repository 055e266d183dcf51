"""JSON request bodies with sample arrays, read with bounded memory.

A body up to ``Settings.json_stream_bytes`` is read whole and parsed by pydantic-core straight
from the bytes (the fast path: a 1e4-sample signal is ~200 kB). A larger one is parsed *as it
arrives* by ijson (yajl2's C parser): the numbers of the top-level sample arrays (``w``, ``t``)
go straight into float64 buffers (8 bytes a sample, no Python float per sample, no copy of the
body), everything else (``dt``, ``metadata``...) is built as usual and validated by the same
pydantic model, with the arrays replaced by placeholders. The model (and so the OpenAPI
document) is unchanged; the answers are those of the fast path:

- a wrong item of an array (boolean, null, text, nested) is pydantic's own error for that item
  (the item is validated alone against ``list[StrictFloat]`` and its index put back); at most
  ``MAX_ITEM_ERRORS`` such errors per array are listed;
- ``NaN``, ``Infinity``, ``-Infinity`` and numbers beyond the float64 range are 422 naming the
  field (``w[12]``, ``dt``, ``control.value``) and the value, as the readers name them;
- malformed JSON is pydantic's ``json_invalid`` (field ``body``), naming yajl's reason;
- limits are checked while the body streams: the body size (``BodyLimitMiddleware``), the count
  of values (commas, counted in each chunk before it is parsed) and of samples per array (413);
  nesting deeper than ``max_json_depth`` (422 naming the top-level field).

Difference from the fast path, by construction of yajl: an *integer* literal beyond 64 bits
(19+ digits, no fraction or exponent, e.g. ``12345678901234567890``) is a 422 naming it (the
fast path reads it as a float); write such numbers with an exponent (``1.2345678901234567e19``).
"""

from __future__ import annotations

import array
import itertools
import json
import math
from typing import Any, TypeVar

import ijson
import numpy as np
from anyio import to_thread
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, StrictFloat, TypeAdapter, ValidationError
from starlette.requests import Request

from service.api import limits
from service.api.problems import invalid, too_large
from service.api.routers._common import body_validation_error
from service.api.settings import Settings

M = TypeVar("M", bound=BaseModel)

try:  # yajl2's C parser, in ijson's wheels (its error messages are read below)
    _BACKEND: Any = ijson.get_backend("yajl2_c")
except ImportError:  # pragma: no cover - a platform without the wheel: slower, same answers
    _BACKEND = ijson

#: The top-level fields read into float64 arrays (``list[StrictFloat]`` in the models).
ARRAY_FIELDS = ("w", "t")
#: Item errors listed per array (a body of a million booleans is one problem, not a million).
MAX_ITEM_ERRORS = 100
#: Bytes parsed per step (off the event loop); a step ends after a delimiter, so no number or
#: ``NaN`` token is ever split between two steps (yajl's error then shows it whole).
STEP_BYTES = 1 << 20

_ITEMS = TypeAdapter(list[StrictFloat])
_NON_FINITE = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}
_DELIMS = " \t\r\n,:[]{}"
#: Bytes a step may end after: no number (nor ``NaN``) token holds them.
_CUT_AFTER = (b",", b"[", b":", b" ", b"\n")


async def read_model(
    request: Request, model: type[M], settings: Settings, arrays: tuple[str, ...] = ARRAY_FIELDS
) -> M:
    """The body of ``request`` validated as ``model``; see the module notes and
    :func:`read_small_or_model`."""
    got = await read_small_or_model(request, model, settings, arrays)
    return validate_small(model, got) if isinstance(got, bytes) else got


def validate_small(model: type[M], body: bytes) -> M:
    """``model`` from a whole small body (pydantic-core parses the bytes); a 422 naming the
    fields, as FastAPI's own (``loc`` under "body")."""
    try:
        return model.model_validate_json(body)
    except ValidationError as exc:
        raise body_validation_error(exc) from None


async def read_small_or_model(
    request: Request, model: type[M], settings: Settings, arrays: tuple[str, ...] = ARRAY_FIELDS
) -> bytes | M:
    """The whole body when it is small (up to ``json_stream_bytes``; the values counted), else
    the model parsed from it as it streamed.

    A route may then validate the small body where the work runs (an analysis worker), with
    :func:`validate_small`.

    Parameters
    ----------
    request : Request
        A request whose body is JSON (not read yet).
    model : type of BaseModel
        The body's model; its fields named in ``arrays`` must be ``list[StrictFloat]``.
    settings : Settings
        ``json_stream_bytes`` (the size above which the body is streamed), ``max_samples``,
        ``max_json_depth``.
    arrays : tuple of str
        Top-level fields read as float64 arrays when streaming.

    Returns
    -------
    bytes or M
        The small body, or the model; the fields in ``arrays`` of a streamed body hold 1-D
        float64 numpy arrays instead of lists.

    Raises
    ------
    RequestValidationError, ApiProblem
        422 naming the field and the value, 413 over the limits.
    """
    head: list[bytes] = []
    size = 0
    stream = request.stream()
    declared = request.headers.get("content-length", "")
    if not (declared.isdigit() and int(declared) > settings.json_stream_bytes):
        async for chunk in stream:
            head.append(chunk)
            size += len(chunk)
            if size > settings.json_stream_bytes:
                break
        else:  # the whole body is here and small: pydantic-core parses it in one piece
            body = b"".join(head)
            limits.check_json_samples(body, settings.max_samples)
            return body
    parser = StreamParser(settings.max_samples, settings.max_json_depth, arrays)
    for chunk in head:
        step = parser.push(chunk)
        if step:
            await to_thread.run_sync(parser.feed, step)
    del head
    async for chunk in stream:
        step = parser.push(chunk)
        if step:  # parsed off the event loop
            await to_thread.run_sync(parser.feed, step)
    found = await to_thread.run_sync(parser.finish)
    return _validate(model, found)


class Parsed:
    """What :class:`StreamParser` found: the other fields, the arrays, the items' errors."""

    def __init__(self) -> None:
        self.rest: dict[str, Any] = {}
        self.arrays: dict[str, np.ndarray] = {}
        self.bad_arrays: set[str] = set()
        self.errors: list[dict[str, Any]] = []


class StreamParser:
    """Push parser of one JSON object (``feed`` bytes, then ``finish``); see the module notes.

    Parameters
    ----------
    max_samples : int
        Most samples per array and (with :func:`limits.check_value_count`'s margin) values.
    max_depth : int
        Deepest nesting of a field's value (``metadata`` itself counts 1, as in
        :func:`limits.check_depth`).
    arrays : tuple of str
        Top-level fields read into float64 arrays.
    step_bytes : int, optional
        Bytes per parsing step (default ``STEP_BYTES``).
    """

    def __init__(
        self,
        max_samples: int,
        max_depth: int,
        arrays: tuple[str, ...] = ARRAY_FIELDS,
        step_bytes: int | None = None,
    ) -> None:
        self.max_samples = max_samples
        self.step_bytes = STEP_BYTES if step_bytes is None else step_bytes
        self.pending = bytearray()
        self.max_depth = max_depth
        self.array_fields = arrays
        self.events = ijson.sendable_list()
        self.coro = _BACKEND.basic_parse_coro(self.events, use_float=True)
        self.out = Parsed()
        self.commas = 0
        self.state = "start"  # start -> key -> value -> key ... -> done
        self.key: str | None = None
        self.buf: array.array | None = None  # the sample array being read
        self.item_errors = 0
        self.builder: ijson.ObjectBuilder | None = None  # a container value being built
        self.path: list[Any] = []  # the builder's open containers: a key or an item index

    # -- input ---------------------------------------------------------------------------
    def push(self, chunk: bytes) -> bytes | None:
        """Take the next chunk of the body; the bytes to :meth:`feed` next, once there are
        ``step_bytes`` of them (cut after a delimiter: no token is split between two steps).

        413 before parsing when the body so far holds more values than allowed.
        """
        self.commas += chunk.count(b",")
        limits.check_value_count(self.commas, self.max_samples)
        pending = self.pending
        pending += chunk
        if len(pending) < self.step_bytes:
            return None
        cut = max(pending.rfind(d) for d in _CUT_AFTER) + 1
        if not cut:  # inside a long token (a string): wait for a delimiter, a while
            if len(pending) < max(4 * self.step_bytes, 4096):
                return None
            cut = len(pending)
        step = bytes(pending[:cut])
        del pending[:cut]
        return step

    def feed(self, data: bytes) -> None:
        """Parse the next bytes of the body."""
        try:
            self.coro.send(data)
        except ijson.JSONError as exc:
            self._take()
            raise self._syntax_error(exc) from None
        self._take()

    def finish(self) -> Parsed:
        """Parse what is left; what was found (422 when the document is incomplete)."""
        if self.pending:
            last, self.pending = bytes(self.pending), bytearray()
            self.feed(last)
        try:
            self.coro.close()
        except ijson.JSONError as exc:
            self._take()
            raise self._syntax_error(exc) from None
        self._take()
        return self.out

    # -- events --------------------------------------------------------------------------
    def _take(self) -> None:
        events = self.events
        n, i = len(events), 0
        while i < n:
            if self.buf is not None and self.builder is None:
                i = self._numbers(events, i)
                if i >= n:
                    break
            ev, val = events[i]
            i += 1
            self._event(ev, val)
        del events[:]

    def _numbers(self, events: list[tuple[str, Any]], i: int) -> int:
        """The hot loop: append the run of numbers from ``events[i]`` to the array being
        read; the index of the first other event."""
        buf = self.buf
        assert buf is not None
        append = buf.append
        k = i
        for ev, val in itertools.islice(events, i, None):
            if ev != "number":
                break
            append(val)  # ints and floats (yajl refuses what float64 cannot hold)
            k += 1
        if len(buf) > self.max_samples:  # as recordings.from_arrays says it (413)
            raise too_large(
                str(self.key),
                len(buf),
                f"{len(buf)} samples (read so far) exceed the limit of {self.max_samples} "
                "(setting SNAPWARN_MAX_SAMPLES)",
            )
        return k

    def _event(self, ev: str, val: Any) -> None:
        if self.builder is not None:
            self._build(ev, val)
        elif self.buf is not None:
            self._array_event(ev, val)
        elif self.state == "start":
            if ev != "start_map":
                raise _not_an_object(ev, val)
            self.state = "key"
        elif self.state == "key":
            if ev == "end_map":
                self.state = "done"
            else:  # map_key
                self.key, self.state = val, "value"
        elif self.key in self.array_fields and ev == "start_array":
            self._forget(self.key)  # a repeated key: the last one counts
            self.buf = array.array("d")
            self.item_errors = 0
        elif ev in ("start_map", "start_array"):
            self.builder = ijson.ObjectBuilder()
            self._build(ev, val)
        else:
            self._store(val)

    def _store(self, value: Any) -> None:
        assert self.key is not None
        self._forget(self.key)  # a repeated key: the last one counts
        self.out.rest[self.key] = value
        self.state = "key"

    def _forget(self, key: str) -> None:
        out = self.out
        out.rest.pop(key, None)
        out.arrays.pop(key, None)
        out.bad_arrays.discard(key)
        out.errors = [e for e in out.errors if e["loc"][0] != key]

    def _array_event(self, ev: str, val: Any) -> None:
        buf = self.buf
        assert buf is not None and self.key is not None
        if ev == "end_array":
            self.out.arrays[self.key] = np.frombuffer(buf, dtype=np.float64)
            if self.item_errors:
                self.out.bad_arrays.add(self.key)
            self.buf, self.state = None, "key"
        elif ev in ("start_map", "start_array"):  # a nested item: built, then refused
            self.builder = ijson.ObjectBuilder()
            self._build(ev, val)
        else:  # boolean, null, string
            self._bad_item(val)

    def _bad_item(self, value: Any) -> None:
        """pydantic's error for this item (validated alone), at its index."""
        buf = self.buf
        assert buf is not None
        index = len(buf)
        buf.append(math.nan)  # keeps the indices of the items after it
        self.item_errors += 1
        if self.item_errors > MAX_ITEM_ERRORS:
            return
        try:
            _ITEMS.validate_json(json.dumps([value]))
        except ValidationError as exc:
            for e in exc.errors():
                e = dict(e)
                e["loc"] = (self.key, index, *e["loc"][1:])
                self.out.errors.append(e)

    def _build(self, ev: str, val: Any) -> None:
        """One event of a container value (``metadata``, ``control``, a nested item)."""
        path = self.path
        if ev in ("start_map", "start_array"):
            if len(path) >= self.max_depth:
                raise invalid(
                    str(self.key),
                    f"<nested {len(path) + 1} deep>",
                    f"nests deeper than {self.max_depth} levels",
                )
            path.append(0 if ev == "start_array" else None)
        elif ev == "map_key":
            path[-1] = val
        elif ev in ("end_map", "end_array"):
            path.pop()
        builder = self.builder
        assert builder is not None
        builder.event(ev, val)
        if ev not in ("start_map", "start_array", "map_key") and path:
            if type(path[-1]) is int:  # a value ended inside an array: the next index
                path[-1] += 1
        if not path:  # the value is complete
            self.builder = None
            if self.buf is not None:
                self._bad_item(builder.value)
            else:
                self._store(builder.value)

    # -- errors --------------------------------------------------------------------------
    def _where(self) -> str:
        """The field being read: ``w[12]``, ``dt``, ``metadata.a[3]``."""
        field = str(self.key)
        if self.buf is not None:
            field += f"[{len(self.buf)}]"
        for p in self.path:
            if type(p) is int:
                field += f"[{p}]"
            elif p is not None:
                field += f".{p}"
        return field

    def _syntax_error(self, exc: Exception) -> Exception:
        """A non-finite or out-of-range number at its field, else ``json_invalid``."""
        reason, token, context = _yajl_reason(str(exc))
        where = self._where() if self.state == "value" else "body"
        if token in _NON_FINITE:
            return invalid(where, _NON_FINITE[token], "must be finite (NaN and Infinity are "
                           "not numbers of JSON)")  # fmt: skip
        if "numeric (floating point) overflow" in reason:
            value = -math.inf if token.startswith("-") else math.inf
            return invalid(where, value, f"must be finite ({token} is beyond the float64 range)")
        if "integer overflow" in reason:
            return invalid(where, token, "is an integer beyond 64 bits: write it with an "
                           "exponent (e.g. 1.5e19) in bodies this large")  # fmt: skip
        return RequestValidationError(
            [{"type": "json_invalid", "loc": ("body",), "msg": f"Invalid JSON: {reason}",
              "input": context, "ctx": {"error": reason}}]
        )  # fmt: skip


def _yajl_reason(message: str) -> tuple[str, str, str]:
    """yajl's reason, the token at its caret and the text around it (``"lexical error:
    invalid char in json text."``, ``"NaN"``, ``'{"w":[1,NaN,3]}'``).

    yajl's verbose message is the reason, the text around the error and a line with ``^``
    under the character where it stopped.
    """
    lines = message.split("\n")
    reason = lines[0].strip()
    if len(lines) < 3 or "^" not in lines[2]:
        return reason, "", ""
    text, at = lines[1], lines[2].index("^")
    start = min(at, len(text))
    while start > 0 and text[start - 1] not in _DELIMS:
        start -= 1
    end = start
    while end < len(text) and text[end] not in _DELIMS:
        end += 1
    return reason, text[start:end], text.strip()


def _not_an_object(ev: str, val: Any) -> RequestValidationError:
    value = {"start_array": "<array>"}.get(ev, val)
    return RequestValidationError(
        [{"type": "model_type", "loc": ("body",), "msg": "Input should be an object",
          "input": value}]
    )  # fmt: skip


def _validate(model: type[M], found: Parsed) -> M:
    """``model`` on the other fields with the arrays as placeholders, then the arrays put in;
    the items' errors and the model's, in the order of the model's fields."""
    doc = dict(found.rest)
    for name, a in found.arrays.items():
        # a short array is validated as it is (pydantic names it: "at least 2 items")
        short = a.size < 2 and name not in found.bad_arrays
        doc[name] = a.tolist() if short else [0.0, 0.0]
    errors = list(found.errors)
    obj = None
    try:
        obj = model.model_validate_json(json.dumps(doc))
    except ValidationError as exc:
        errors += exc.errors()
    if errors or obj is None:
        order = {name: i for i, name in enumerate(model.model_fields)}
        errors.sort(key=lambda e: order.get(e["loc"][0] if e["loc"] else "", len(order)))
        raise RequestValidationError([{**e, "loc": ("body", *e["loc"])} for e in errors])
    big = {k: a for k, a in found.arrays.items() if a.size >= 2}
    return obj.model_copy(update=big)
