"""``POST /v1/predictions``: mu* from a sweep table already measured (the predict document).

The door of ``snapwarn predict TABLE --json`` for software that measures its own frequencies:
the body holds the table's columns (``mu`` with ``sigma2`` or ``omega``...) and the CLI's
options; the answer is the same :class:`~service.schemas.Prediction` document (converted by
``service.convert.prediction``). The body is parsed, validated and predicted whole in an
analysis worker, within the request time limit; this module only moves bytes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from fastapi import APIRouter, Request, Response
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError

from service import convert
from service.analysis.predict import predict
from service.api.problems import ApiProblem, as_problems, invalid
from service.api.routers._common import problems
from service.api.state import StateDep
from service.schemas import Prediction, PredictionRequest
from service.schemas.predictions import OMEGA_UNIT_FACTORS, TABLE_FIELDS

router = APIRouter(prefix="/v1/predictions", tags=["predictions"])

#: Validation errors listed per answer (a body of a million NaNs is one problem, not a million).
MAX_ERRORS = 100
#: Values a body may hold besides its table's (the options, a scalar w_static_std...).
_SPARE_VALUES = 1000


@router.post(
    "",
    response_model=Prediction,
    summary="Predict mu* from a sweep table (the `snapwarn predict TABLE --json` document)",
    responses=problems(401, 413, 422),
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {
                "application/json": {"schema": {"$ref": "#/components/schemas/PredictionRequest"}}
            },
        }
    },
)
async def create_prediction(request: Request, state: StateDep) -> Any:
    """Give ``mu`` with ``sigma2`` or ``omega`` (or both, when they agree: ``sigma2`` is
    used), their standard deviations, the static deflection and the options of ``snapwarn
    predict`` (``damping``, ``transition``, ``a``); at most ``SNAPWARN_MAX_PREDICTION_POINTS``
    points.

    Invalid tables are 422 problems naming the field and the value (``mu[3]``, ``sigma2``,
    ``omega`` where it contradicts ``sigma2``, ``a``...), as the numerics name them.
    """
    s = state.settings
    body = await _read_body(request, s.max_prediction_points)
    kind, out = await state.run(prediction_from_body, body, s.max_prediction_points)
    if kind == "invalid":
        raise RequestValidationError(out)
    return Response(out, media_type="application/json")


async def _read_body(request: Request, max_points: int) -> bytes:
    """The whole body, refused (413) as it arrives once it holds more values (commas) than
    every column of ``max_points`` rows could: no table that big is parsed."""
    limit = len(TABLE_FIELDS) * max_points + _SPARE_VALUES
    parts: list[bytes] = []
    commas = 0
    async for chunk in request.stream():
        commas += chunk.count(b",")
        if commas > limit:
            raise ApiProblem(
                413,
                f"body: holds more than {limit} values, more than {len(TABLE_FIELDS)} columns "
                f"of {max_points} points (setting SNAPWARN_MAX_PREDICTION_POINTS)",
                field="body",
                value=f"more than {limit} values",
                headers={"Connection": "close"},  # the rest of the body is left unread
            )
        parts.append(chunk)
    return b"".join(parts)


def prediction_from_body(body: bytes, max_points: int) -> tuple[str, Any]:
    """The whole work of a prediction request, in an analysis worker.

    Returns ``("json", bytes)``: the ``Prediction`` document, serialised here; or
    ``("invalid", errors)``: the body's validation errors (FastAPI's form, ``loc`` under
    "body"). Invalid tables raise :class:`~service.api.problems.ApiProblem` (422 naming the
    field and the value; it crosses the process boundary).
    """
    try:
        req = PredictionRequest.model_validate_json(body)
    except ValidationError as exc:
        errors = exc.errors(include_url=False, include_context=False)[:MAX_ERRORS]
        return "invalid", [{**e, "loc": ("body", *e["loc"])} for e in errors]
    mu, kw = table_arguments(req, max_points)
    with as_problems("body"):
        pred = predict(mu, **kw)
    return "json", convert.prediction(pred).model_dump_json().encode()


def table_arguments(req: PredictionRequest, max_points: int) -> tuple[np.ndarray, dict[str, Any]]:
    """``mu`` and the keyword arguments of :func:`service.analysis.predict.predict` for
    ``req``, as ``snapwarn predict`` builds them from a table (rates in ``omega_unit``
    converted to rad/s as the CLI converts a header's unit). Lengths, signs and the order of
    ``mu`` are the numerics' to judge (their errors name the field)."""
    for name in TABLE_FIELDS:
        v = getattr(req, name)
        if isinstance(v, list) and len(v) > max_points:
            raise invalid(
                name,
                len(v),
                f"points exceed the limit of {max_points} (setting SNAPWARN_MAX_PREDICTION_POINTS)",
            )
    if req.omega_unit is not None and req.omega is None and req.sigma2 is not None:
        raise invalid("omega_unit", req.omega_unit, "goes with omega, not with sigma2")
    factor = OMEGA_UNIT_FACTORS[req.omega_unit] if req.omega_unit not in (None, "rad/s") else None
    kw: dict[str, Any] = {}
    for name in TABLE_FIELDS[1:]:
        v = getattr(req, name)
        if v is None:
            continue
        arr = np.asarray(v, dtype=np.float64)
        kw[name] = arr * factor if factor is not None and name in ("omega", "omega_std") else arr
    for name in ("damping", "transition", "a"):
        if getattr(req, name) is not None:
            kw[name] = getattr(req, name)
    kw["level"] = req.level
    return np.asarray(req.mu, dtype=np.float64), kw
