"""Booleans are not numbers: every numeric field of every request model refuses ``true``.

pydantic's lax mode reads ``true`` as 1 / 1.0 (``{"simulate": {"damping": true}}`` ran a sweep
with damping 1). The request models use one shared type (``service.schemas.common.Number`` /
``Integer``); this test walks every model a request body can reach in the committed OpenAPI
document (and the JSON live-record body), puts ``true`` in each numeric leaf and asks for an
error at exactly that place; then a few doors over HTTP: 422 naming the field and the value.
"""

from __future__ import annotations

import importlib
import json
import pkgutil
import types
import typing
from pathlib import Path
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import pytest
from pydantic import BaseModel, ValidationError

import service.schemas

SPEC = Path(__file__).resolve().parents[2] / "openapi" / "openapi.json"
#: Request bodies that the OpenAPI document describes by hand (multipart/JSON alternatives).
EXTRA = ("LiveRecordIn",)


def _models() -> dict[str, type[BaseModel]]:
    out: dict[str, type[BaseModel]] = {}
    for mod in pkgutil.iter_modules(service.schemas.__path__):
        m = importlib.import_module(f"service.schemas.{mod.name}")
        for name, obj in vars(m).items():
            mine = isinstance(obj, type) and obj.__module__ == m.__name__
            if mine and issubclass(obj, BaseModel):
                out[name] = obj
    return out


def _request_models() -> list[type[BaseModel]]:
    """The models reachable from any operation's request body in the committed spec."""
    spec = json.loads(SPEC.read_text())
    schemas = spec["components"]["schemas"]
    names: set[str] = set()

    def walk(o: Any) -> None:
        if isinstance(o, dict):
            for k, v in o.items():
                if k == "$ref" and (n := v.rsplit("/", 1)[-1]) not in names:
                    names.add(n)
                    walk(schemas[n])
                else:
                    walk(v)
        elif isinstance(o, list):
            for v in o:
                walk(v)

    for ops in spec["paths"].values():
        for op in ops.values():
            walk(op.get("requestBody", {}))
    models = _models()
    names |= set(EXTRA)
    missing = sorted(n for n in names if n not in models and not n.startswith("Body_"))
    assert not missing, f"request schemas without a model in service.schemas: {missing}"
    return [models[n] for n in sorted(names) if n in models]


def _probe(ann: Any) -> tuple[Any, tuple] | None:
    """A JSON value holding ``true`` where ``ann`` expects a number, and the path to it."""
    if ann in (int, float):
        return True, ()
    origin, args = get_origin(ann), get_args(ann)
    if origin is Annotated:
        return _probe(args[0])
    if origin in (Union, types.UnionType):
        if bool in args:  # a boolean is one of the accepted kinds
            return None
        for a in args:
            if (r := _probe(a)) is not None:
                return r
        return None
    if origin is list:
        r = _probe(args[0])
        return ([r[0]], (0, *r[1])) if r else None
    if origin is tuple and args and args[-1] is not Ellipsis:
        r = _probe(args[0])
        return ([r[0], *[0.5] * (len(args) - 1)], (0, *r[1])) if r else None
    if origin is dict:
        r = _probe(args[1])
        return ({"k": r[0]}, ("k", *r[1])) if r else None
    return None  # str, bool, Literal, nested models (walked as models of their own), Any


def _cases() -> list[tuple[str, type[BaseModel], str, Any, tuple]]:
    cases = []
    for model in _request_models():
        hints = typing.get_type_hints(model, include_extras=True)
        for name, field in model.model_fields.items():
            r = _probe(hints[name])
            if r is not None:
                key = field.alias or name
                cases.append((f"{model.__name__}.{key}", model, key, r[0], (key, *r[1])))
    return cases


CASES = _cases()


def test_the_walk_finds_the_numeric_fields() -> None:
    """Not vacuous: the scene's, the sweep's, the live options', the atlas range's numbers."""
    ids = {c[0] for c in CASES}
    for must in ("SimulationRequest.damping", "SimulationRequest.seed", "SnapRequest.dmu",
                 "SimulatedSweep.damping", "SimulatedSweep.max_measurements",
                 "SweepRequest.band", "SweepMeasurement.control_value", "LiveOptions.budget",
                 "LiveRecordIn.control", "AtlasRange.num", "AtlasRange.from",
                 "SignalIn.t0", "Control.value", "PredictionRequest.mu"):  # fmt: skip
        assert must in ids, (must, sorted(ids))
    assert len(CASES) >= 50, len(CASES)
    assert _probe(Literal["a"]) is None and _probe(bool | None) is None


@pytest.mark.parametrize(("label", "model", "key", "value", "loc"), CASES,
                         ids=[c[0] for c in CASES])  # fmt: skip
def test_a_boolean_is_refused_where_a_number_is_expected(label, model, key, value, loc) -> None:  # noqa: ANN001
    with pytest.raises(ValidationError) as exc:
        model.model_validate_json(json.dumps({key: value}))
    at = [e for e in exc.value.errors() if _place(e["loc"]) == loc and e["input"] is True]
    assert at, (label, exc.value.errors())
    assert {e["type"] for e in at} <= {"float_type", "int_type"}, at


def _place(loc: tuple) -> tuple:
    """The error's place without the tags pydantic adds inside a union (``'list[...]'``)."""
    return tuple(p for k, p in enumerate(loc) if k == 0 or isinstance(p, int) or p == "k")


def test_numbers_still_pass() -> None:
    """An integer where a float is expected is a number (JSON does not tell 1 from 1.0)."""
    from service.schemas import SimulationRequest
    from service.schemas.sweeps import SweepRequest

    r = SimulationRequest.model_validate_json('{"damping": 0, "mu": 1, "seed": 3, "elements": 8}')
    assert (r.damping, r.mu, r.seed, r.elements) == (0.0, 1.0, 3, 8)
    s = SweepRequest.model_validate_json('{"simulate": {"damping": 1}, "band": [1, 2.5]}')
    assert s.simulate is not None and s.simulate.damping == 1.0 and s.band == (1.0, 2.5)


DOORS = [
    ("/v1/simulations", {"model": "normal-form", "damping": True}, "damping"),
    ("/v1/simulations", {"model": "normal-form", "seed": False}, "seed"),
    ("/v1/snaps", {"dmu": True}, "dmu"),
    ("/v1/sweeps", {"simulate": {"damping": True}}, "simulate.damping"),
    ("/v1/sweeps", {"mode": "live", "live": {"budget": True}}, "live.budget"),
    ("/v1/sweeps", {"simulate": {}, "band": [True, 2.0]}, "band[0]"),
    ("/v1/signals", {"dt": 0.1, "w": [1.0, 2.0, 3.0], "t0": True}, "t0"),
    ("/v1/signals", {"dt": 0.1, "w": [1.0, 2.0, 3.0], "control": {"value": True}},
     "control.value"),
]  # fmt: skip


@pytest.mark.anyio
@pytest.mark.parametrize(("path", "body", "field"), DOORS, ids=[d[2] for d in DOORS])
async def test_the_doors_answer_422_naming_the_field_and_the_value(asgi, path, body, field) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.post(path, json=body)
    assert r.status_code == 422, (r.status_code, r.text[:300])
    errors = [e for e in r.json().get("errors", []) if e.get("field") == field]
    assert errors, r.json()
    assert isinstance(errors[0]["value"], bool), errors
