"""Big JSON bodies are parsed as a stream (``service.api.jsonbody``, ijson/yajl2): the answers
are those of the one-piece parse by pydantic-core (the reference: the same app with streaming
off), the samples are bit-exact float64, limits hold while the body streams, and the result
does not depend on how the body is cut into chunks."""

from __future__ import annotations

import io
import json
import random
from collections.abc import AsyncIterator

import httpx2
import numpy as np
import pytest
from _svc_helpers import test_settings
from fastapi.exceptions import RequestValidationError

from service.api import create_app, jsonbody
from service.api.problems import ApiProblem
from service.schemas import DetectionRequest, SignalIn

pytestmark = pytest.mark.anyio

MAX_SAMPLES = 5000


def _exact_values() -> list[float]:
    """float64 values that a lossy reader would change: extremes, subnormals, -0.0, ties."""
    rng = np.random.default_rng(7)
    special = [0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
               -1.7976931348623157e308, 0.1, 1 / 3, 9007199254740993.0, 1e-300]  # fmt: skip
    return special + (rng.standard_normal(200) * 10.0 ** rng.integers(-30, 30, 200)).tolist()


def _doc(**kw: object) -> str:
    return json.dumps({"dt": 0.1, "w": [1.0, 2.0, 3.0], **kw}, allow_nan=True)


#: Answered exactly alike (status and every error, or the same stored signal).
SAME = [
    json.dumps({"dt": 0.001, "w": _exact_values()}),
    json.dumps(
        {
            "t": [0.5 + 0.25 * k for k in range(50)],
            "w": list(range(50)),
            "unit": "s",
            "value_unit": "mm",
            "name": "r\u00e9cord \u2603",
            "control": {"name": "load", "value": 1.25, "unit": "N"},
            "metadata": {"rig": "A", "n": [1, 2, {"x": None, "y": True}], "e": {}},
        }
    ),
    json.dumps({"t": [round(0.1 * k, 2) for k in range(40)], "w": [1.0] * 40}),  # rounded t
    _doc(w=[]),
    _doc(w=[1]),
    _doc(w=[[1, 2], [3]]),
    _doc(w=[1, "a", 3]),
    _doc(w=[True, 2, 3]),
    _doc(w=[None, 1, 2]),
    _doc(w=[1, 2, {"a": 1}]),
    _doc(w=None),
    _doc(w="abc"),
    _doc(w={}),
    _doc(t=[0, 1, False]),
    _doc(t=[0, 2, 1], dt=None),
    _doc(t=[0, 1, 2, 3.5], w=[1, 2, 3, 4], dt=None),
    _doc(dt=None),
    _doc(dt=-1),
    _doc(dt="0.1"),
    _doc(t=[0, 1, 2]),  # dt and t
    _doc(colour="red"),
    _doc(control={"value": "x"}),
    _doc(name="n" * 501),
    _doc(resample="yes"),
    _doc(metadata=[1, 2]),
    _doc(metadata={"a": float("nan")}),
    _doc(metadata={"a": [1, 2, {"b": float("inf")}]}),
    '{"dt": 0.1, "w": [true, 2], "w": [1, 2, 3]}',  # a repeated key: the last one counts
    '{"dt": 0.1, "w": [1, 2, 3], "w": [1, "a"]}',
    '{"dt": 0.1, "w": [1, 2, 3], "metadata": ' + '{"a": ' * 40 + "1" + "}" * 40 + "}",
    "3",
    "null",
    '"w"',
]

#: The same status, field and value (the message may word it differently).
SAME_FIELD = [
    _doc(w=[1, float("nan"), 3]),
    _doc(w=[1, 2, float("inf")]),
    _doc(t=[0, 1, float("-inf")], dt=None),
    _doc(dt=float("nan")),
    _doc(control={"value": float("nan")}),
    '{"dt": 0.1, "w": [1, 1e400, 3]}',
    '{"dt": 0.1, "w": [1, -1e400, 3]}',
    '{"dt": 1e400, "w": [1, 2, 3]}',
    json.dumps({"dt": 0.1, "w": [0.5] * (MAX_SAMPLES + 1)}),
]

#: Malformed JSON: 422 on field "body" (pydantic-core and yajl word the reason differently).
MALFORMED = [
    '{"dt": 0.1, "w": [1, 2',
    '{"dt": 0.1, "w": [1, 2]} x',
    '{"dt": 0.1, "w": [1, 2],}',
    '{"dt": 0.1, "w": [1, 2,]}',
    '{"dt": 0.1 "w": [1, 2]}',
    '{"dt": 0.1, "w": [1, nan]}',
    "",
]


@pytest.fixture(scope="module")
async def pair(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[tuple]:
    """Two apps alike but for ``json_stream_bytes``: 0 (every body streams) and the default
    (these small bodies are parsed in one piece: the reference)."""
    d = tmp_path_factory.mktemp("jsonbody")
    apps = [
        create_app(
            test_settings(
                f"sqlite:///{d / f'{k}.db'}",
                executor="thread",
                warm_pool=False,
                run_jobs=False,
                max_samples=MAX_SAMPLES,
                json_stream_bytes=k,
            )
        )  # fmt: skip
        for k in (0, 1 << 20)
    ]
    async with apps[0].router.lifespan_context(apps[0]):
        async with apps[1].router.lifespan_context(apps[1]):
            clients = [
                httpx2.AsyncClient(transport=httpx2.ASGITransport(app=a), base_url="http://asgi")
                for a in apps
            ]
            try:
                yield tuple(clients)
            finally:
                for c in clients:
                    await c.aclose()


def _chunks(body: bytes, seed: int) -> AsyncIterator[bytes]:
    """The body in random small pieces (a request without Content-Length)."""
    rng = random.Random(seed)

    async def gen() -> AsyncIterator[bytes]:
        i = 0
        while i < len(body):
            n = rng.randint(1, 97)
            yield body[i : i + n]
            i += n

    return gen()


async def _post(client: httpx2.AsyncClient, path: str, doc: str, chunked: bool) -> httpx2.Response:
    body = doc.encode()
    content = _chunks(body, len(body)) if chunked else body
    return await client.post(path, content=content, headers={"content-type": "application/json"})


async def _answer(client: httpx2.AsyncClient, r: httpx2.Response) -> tuple:
    """What a client sees: the problem's errors, or the stored signal (metadata and samples)."""
    doc = r.json()
    if r.status_code >= 400:
        return r.status_code, doc["errors"]
    if "id" not in doc:  # a detection
        return r.status_code, doc
    data = await client.get(f"/v1/signals/{doc['id']}/data", params={"format": "npy"})
    for k in ("id", "created_at"):
        doc.pop(k)
    return r.status_code, doc, np.load(io.BytesIO(data.content)).tobytes()


@pytest.mark.parametrize("chunked", [False, True], ids=["length", "chunked"])
@pytest.mark.parametrize("doc", SAME, ids=range(len(SAME)))
async def test_streamed_body_is_answered_as_the_one_piece_parse(pair, doc, chunked) -> None:  # noqa: ANN001
    stream, reference = pair
    want = await _answer(reference, await _post(reference, "/v1/signals", doc, False))
    got = await _answer(stream, await _post(stream, "/v1/signals", doc, chunked))
    assert got == want


@pytest.mark.parametrize("doc", SAME_FIELD, ids=range(len(SAME_FIELD)))
async def test_non_finite_and_oversized_name_the_same_field_and_value(pair, doc) -> None:  # noqa: ANN001
    stream, reference = pair
    want = await reference.post("/v1/signals", content=doc.encode(),
                                headers={"content-type": "application/json"})  # fmt: skip
    got = await _post(stream, "/v1/signals", doc, True)
    assert want.status_code in (413, 422)
    assert got.status_code == want.status_code, got.text
    assert got.headers["content-type"] == "application/problem+json"
    first = {k: got.json()["errors"][0][k] for k in ("field", "value")}
    assert first == {k: want.json()["errors"][0][k] for k in ("field", "value")}


@pytest.mark.parametrize("doc", MALFORMED, ids=range(len(MALFORMED)))
async def test_malformed_json_is_a_422_on_the_body(pair, doc) -> None:  # noqa: ANN001
    for client in pair:
        r = await _post(client, "/v1/signals", doc, client is pair[0])
        assert r.status_code == 422, r.text
        e = r.json()["errors"][0]
        assert e["field"] == "body" and e["message"].startswith("Invalid JSON"), e


DETECT = [
    json.dumps(
        {
            "dt": 0.01,
            "w": (np.sin(np.arange(3000) * 0.3) * np.exp(-0.001 * np.arange(3000))).tolist(),
        }
    ),  # noqa: E501
    json.dumps(
        {
            "t": [0.01 * k for k in range(400)],
            "w": np.cos(np.arange(400) * 0.5).tolist(),
            "method": "esprit",
        }
    ),  # fmt: skip
    json.dumps({"signal_id": "nope", "w": [1, 2]}),
    json.dumps({"dt": 0.1, "w": [1, False, 3], "method": "magic"}),
    json.dumps({"dt": 0.1, "w": [1, 2, 3], "extra": 1}),
    json.dumps({"dt": 0.1}),
]


@pytest.mark.parametrize("doc", DETECT, ids=range(len(DETECT)))
async def test_detections_stream_alike(pair, doc) -> None:  # noqa: ANN001
    stream, reference = pair
    want = await _answer(reference, await _post(reference, "/v1/detections", doc, False))
    got = await _answer(stream, await _post(stream, "/v1/detections", doc, True))
    assert got == want


async def test_the_models_read_their_samples_as_strict_float_lists() -> None:
    """The streamed arrays stand for ``list[StrictFloat]`` fields (their items' errors are
    that type's): a change of the models must be followed here."""
    for model in (SignalIn, DetectionRequest):
        for name in jsonbody.ARRAY_FIELDS:
            ann = model.model_fields[name].annotation
            assert "list[typing.Annotated[float, Strict(strict=True)]]" in str(ann), (model, ann)


async def test_big_integer_literals_are_named_not_misread(pair) -> None:
    """yajl reads integers in 64 bits: a longer integer literal in a streamed body is a 422
    naming it (documented); the one-piece parse reads it as a float."""
    stream, reference = pair
    doc = '{"dt": 0.1, "w": [1, 12345678901234567890123, 3]}'
    r = await _post(stream, "/v1/signals", doc, True)
    assert r.status_code == 422
    assert r.json()["errors"][0] | {"message": ""} == {
        "field": "w[1]", "value": "12345678901234567890123", "message": ""}  # fmt: skip
    assert (await _post(reference, "/v1/signals", doc, False)).status_code == 201
    r = await _post(stream, "/v1/signals", doc.replace("12345678901234567890123", "1.2e22"), True)
    assert r.status_code == 201, r.text


# -- the parser alone: cut anywhere, the same result ----------------------------------------


def _parse(body: bytes, chunk: int, step: int) -> tuple:
    p = jsonbody.StreamParser(MAX_SAMPLES, 32, step_bytes=step)
    try:
        for i in range(0, max(len(body), 1), chunk):
            s = p.push(body[i : i + chunk])
            if s:
                p.feed(s)
        m = jsonbody._validate(SignalIn, p.finish())
    except ApiProblem as e:
        return e.status, e.errors[0]["field"], e.errors[0]["value"]
    except RequestValidationError as e:
        return tuple((x["type"], x["loc"]) for x in e.errors())
    return tuple((k, np.asarray(v).tobytes() if k in ("w", "t") and v is not None else v)
                 for k, v in m)  # fmt: skip


@pytest.mark.parametrize("doc", SAME + SAME_FIELD + MALFORMED)
def test_chunk_boundaries_do_not_change_the_result(doc: str) -> None:
    body = doc.encode()
    whole = _parse(body, len(body) + 1, 1 << 30)
    for chunk, step in ((1, 1), (3, 7), (5, 2), (64, 100), (1000, 1)):
        assert _parse(body, chunk, step) == whole, (chunk, step)


def test_values_are_counted_before_they_are_parsed() -> None:
    """More commas than 2 x max_samples (+ margin) is a 413 on the chunk that brings them,
    before the parser sees it (the rest of the bytes need not even be JSON)."""
    p = jsonbody.StreamParser(1000, 32)
    p.push(b'{"dt": 0.1, "w": [')
    with pytest.raises(ApiProblem) as ei:
        p.push(b"x," * 110_000)
    assert ei.value.status == 413 and ei.value.errors[0]["field"] == "w"


def test_a_sample_array_over_the_limit_stops_the_parse() -> None:
    p = jsonbody.StreamParser(1000, 32, step_bytes=64)
    body = b'{"dt": 0.1, "w": [' + b"0.5," * 5000
    with pytest.raises(ApiProblem) as ei:
        for i in range(0, len(body), 64):
            s = p.push(body[i : i + 64])
            if s:
                p.feed(s)
    e = ei.value.errors[0]
    assert ei.value.status == 413 and e["field"] == "w" and 1000 < e["value"] <= 1100


def test_item_errors_are_bounded() -> None:
    n = 50_000
    body = json.dumps({"dt": 0.1, "w": [True] * n}).encode()
    p = jsonbody.StreamParser(10 * n, 32)
    p.feed(body)
    found = p.finish()
    assert len(found.errors) == jsonbody.MAX_ITEM_ERRORS and found.arrays["w"].size == n
    with pytest.raises(RequestValidationError) as ei:
        jsonbody._validate(SignalIn, found)
    assert ei.value.errors()[0]["loc"] == ("body", "w", 0)
