"""``/v1/sweeps``: a sweep of measurements (recorded or simulated) -> a job -> the warning."""

from __future__ import annotations

import math
from typing import Annotated, Any

from anyio import to_thread
from fastapi import APIRouter, Query, Response
from fastapi.responses import JSONResponse

from service import convert, recordings
from service.analysis.pipeline import sweep_from_signals, warn
from service.analysis.sweep_policy import SweepPlan
from service.api import limits, plots
from service.api.auth import CallerDep
from service.api.jobs import JobContext, job_handler
from service.api.problems import ApiProblem, as_problems, invalid, not_found, too_large
from service.api.routers._common import MAX_OFFSET, problems
from service.api.routers.live import create_live
from service.api.state import AppState, StateDep
from service.api.sweep_views import sweep_doc, sweep_units
from service.schemas import Sweep, SweepPage, SweepRequest

router = APIRouter(prefix="/v1/sweeps", tags=["sweeps"])


def _check_batch_fields(req: SweepRequest) -> None:
    """A batch sweep takes ``control`` (the name and unit of its recorded control values, shown
    on its page and charts) but no live options; a simulated one steps the simulator's own
    non-dimensional mu, so it takes neither. Refused with a 422 naming the field, never
    ignored."""
    if req.live is not None:
        raise invalid("live", req.live.model_dump(mode="json", exclude_unset=True),
                      "are the options of a live sweep: send \"mode\": \"live\" for an open "
                      "sweep fed record by record, or leave 'live' out")  # fmt: skip
    for name in ("band", "notch"):
        if getattr(req, name) is not None and req.simulate is not None:
            raise invalid(name, getattr(req, name), "is a detector option of recorded signals: "
                          "a simulated sweep has none, leave it out")  # fmt: skip
    if req.control is not None and req.simulate is not None:
        raise invalid("control", req.control.model_dump(mode="json", exclude_unset=True),
                      "names a recorded control: a simulated sweep steps the simulator's "
                      "non-dimensional mu, leave 'control' out")  # fmt: skip


def _unit_conflict(req: SweepRequest, k: int, given: Any, row: Any) -> None:
    """422 when ``control.unit`` contradicts the unit a signal's own control value was stored
    with (a value given in the request is taken in ``control.unit``)."""
    unit = req.control.unit if req.control is not None else None
    if unit is None or given is not None or row.control_unit in (None, unit):
        return
    raise invalid(
        "control.unit", unit,
        f"contradicts measurements[{k}] (signal {row.id!r}), whose control value was stored in "
        f"{row.control_unit!r}: give its control_value in {unit!r}, or leave control.unit out",
    )  # fmt: skip


def _check_units(req: SweepRequest, rows: list[Any]) -> None:
    """422 at the door for signals whose units cannot go in one sweep: control values read from
    the signals in different units (and no ``control.unit`` to give them in), or records in
    different time units of which one is missing or unknown (known ones are brought to
    seconds: :func:`service.recordings.common_time_base`)."""
    ms = req.measurements or []
    given = req.control.unit if req.control is not None else None
    cunits = [given if m.control_value is not None else r.control_unit for m, r in zip(ms, rows)]
    if given is None and len(set(cunits)) > 1:
        listing = ", ".join(f"measurements[{k}]: {u or 'none given'}" for k, u in enumerate(cunits))
        raise invalid(
            "measurements", listing,
            "hold control values stored in different units: give each one's control_value in "
            "one unit and name it in control.unit",
        )  # fmt: skip
    try:
        recordings.common_time_base([r.unit for r in rows], [r.id for r in rows])
    except recordings.RecordingError as exc:
        raise invalid("measurements", exc.value, str(exc)) from None


async def _resolve_measurements(
    req: SweepRequest, state: AppState, scope: str | None
) -> list[dict[str, Any]]:
    ms = req.measurements or []
    limit = state.settings.max_sweep_signals
    least = state.settings.min_sweep_signals
    if len(ms) < least:
        raise invalid("measurements", len(ms), f"need at least {least} signals, got {len(ms)}")
    if len(ms) > limit:
        raise too_large(
            "measurements",
            len(ms),
            f"{len(ms)} measurements exceed the limit of "
            f"{limit} (setting SNAPWARN_MAX_SWEEP_SIGNALS)",
        )
    out, rows = [], []
    for k, m in enumerate(ms):
        row = await to_thread.run_sync(state.store.get_signal_meta, m.signal_id, scope)
        if row is None:
            raise invalid(f"measurements[{k}].signal_id", m.signal_id, "is not a stored signal")
        _unit_conflict(req, k, m.control_value, row)
        rows.append(row)
        value = m.control_value if m.control_value is not None else row.control_value
        if value is None:
            raise invalid(
                f"measurements[{k}].control_value",
                None,
                "is required: the signal was stored without a control value",
            )
        if not math.isfinite(value):
            raise invalid(f"measurements[{k}].control_value", value, "must be finite")
        out.append({"signal_id": m.signal_id, "control_value": float(value),
                    "options": m.detect_options(req.notch)})  # fmt: skip
    _check_units(req, rows)
    # records sharing a control value are averaged by the predictor: they count once
    distinct = len({m["control_value"] for m in out})
    if distinct < state.settings.min_sweep_signals:
        raise invalid(
            "measurements", distinct,
            f"hold {distinct} distinct control values ({len(out)} signals): a sweep needs at "
            f"least {state.settings.min_sweep_signals} (signals sharing a value are averaged "
            "into one point)",
        )  # fmt: skip
    return out


@router.post(
    "",
    status_code=202,
    response_model=Sweep,
    summary="Start a sweep: recorded signals with their control values, or a simulated one",
    responses={
        201: {"model": Sweep, "description": "A live sweep, open for records."},
        **problems(401, 413, 422),
    },
)
async def create_sweep(req: SweepRequest, state: StateDep, caller: CallerDep) -> JSONResponse:
    """Answers 202 with the sweep and its job; poll ``/v1/sweeps/{id}`` or ``/v1/jobs/{id}``.

    ``control`` (``{"name", "unit"}``) names the control values of recorded signals: kept with
    the request and used on the sweep's page and charts (422 when its unit contradicts the unit
    a signal's own control value was stored in). ``live`` options, and a ``control`` for a
    simulated sweep, are refused with a 422 naming the field.

    With ``"mode": "live"`` answers 201 with an open sweep (``service.api.routers.live``)."""
    if req.mode == "live":
        return await create_live(req, state, caller)
    if (req.measurements is None) == (req.simulate is None):
        raise invalid("measurements", None, "give exactly one of 'measurements' or 'simulate'")
    _check_batch_fields(req)
    if req.measurements is not None:
        kind = "sweep-signals"
        resolved = await _resolve_measurements(req, state, caller.scope)
        params: dict[str, Any] = {"measurements": resolved}
        if req.band is not None:
            lo, hi = req.band
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
                raise invalid("band", list(req.band), "must be two finite numbers 0 <= lo < hi")
            params["band"] = [lo, hi]
    else:
        kind = "sweep-simulated"
        params = req.simulate.model_dump(exclude_none=True)
        from sim.scene import MAX_DAMPING

        if params.get("damping") is not None and params["damping"] > MAX_DAMPING:
            raise invalid("simulate.damping", params["damping"],
                          f"must be <= {MAX_DAMPING:g} (a ratio to the bending time scale)")
    await to_thread.run_sync(limits.check_queue, state.store, caller.owner, state.settings)
    request = req.model_dump(mode="json", exclude_none=True)
    if req.control is not None:  # what the user named, not the defaults of a live sweep
        request["control"] = req.control.model_dump(mode="json", exclude_unset=True,
                                                    exclude_none=True)  # fmt: skip
    sweep, job = await to_thread.run_sync(
        lambda: state.store.create_sweep(
            kind,
            request,
            params,
            req.name,
            owner=caller.owner,
            time_limit_s=state.settings.job_time_limit_s,
            max_active=state.settings.max_active_jobs_per_owner,
        )
    )
    if state.runner is not None:
        state.runner.wake()
    doc = Sweep.model_validate(sweep_doc(sweep, job)).model_dump(mode="json")
    return JSONResponse(doc, status_code=202, headers={"Location": f"/v1/sweeps/{sweep.id}"})


@router.get(
    "",
    response_model=SweepPage,
    summary="Sweeps, newest first (the caller's own; an admin key sees all)",
    responses=problems(401, 422),
)
async def list_sweeps(
    state: StateDep,
    caller: CallerDep,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
) -> dict[str, Any]:
    pairs, total = await to_thread.run_sync(
        lambda: state.store.list_sweeps(limit, offset, scope=caller.scope)
    )
    return {
        "items": [sweep_doc(s, j) for s, j in pairs],
        "total": total,
        "limit": limit,
        "offset": offset,
    }


async def _get(state: AppState, sweep_id: str, scope: str | None) -> tuple[Any, Any]:
    found = await to_thread.run_sync(state.store.get_sweep, sweep_id, scope)
    if found is None:
        raise not_found("sweep", sweep_id)
    return found


@router.get(
    "/{sweep_id}",
    response_model=Sweep,
    summary="A sweep: measurements, classification, prediction, alarm",
    responses=problems(401, 404),
)
async def get_sweep(sweep_id: str, state: StateDep, caller: CallerDep) -> dict[str, Any]:
    sweep, job = await _get(state, sweep_id, caller.scope)
    return sweep_doc(sweep, job)


async def _plot(sweep_id: str, state: AppState, fmt: str, scope: str | None) -> Response:
    sweep, job = await _get(state, sweep_id, scope)
    if job.status != "succeeded":
        raise ApiProblem(
            409,
            f"sweep {sweep_id!r} is {job.status}; its chart exists once it succeeded",
            field="status",
            value=job.status,
        )
    units = await sweep_units(state, scope, sweep)  # the user's control name and units
    body = await state.run(_render, job.result, sweep.name or sweep_id, fmt, units)
    return Response(body, media_type=plots.MEDIA[fmt])


def _render(doc: dict[str, Any], title: str, fmt: str, units: dict[str, Any]) -> bytes:
    return plots.sweep_plot(
        doc,
        title=title,
        fmt=fmt,
        control_name=units["control_name"],
        control_unit=units["control_unit"],
        time_unit=units["time_unit"],
    )


@router.get(
    "/{sweep_id}/plot.png",
    summary="T(mu), the extrapolation and mu*'s interval (PNG)",
    response_class=Response,
    responses={
        200: {"content": {"image/png": {}}, "description": "PNG chart."},
        **problems(401, 404, 409),
    },
)
async def plot_sweep_png(sweep_id: str, state: StateDep, caller: CallerDep) -> Response:
    return await _plot(sweep_id, state, "png", caller.scope)


@router.get(
    "/{sweep_id}/plot.svg",
    summary="T(mu), the extrapolation and mu*'s interval (SVG)",
    response_class=Response,
    responses={
        200: {"content": {"image/svg+xml": {}}, "description": "SVG chart."},
        **problems(401, 404, 409),
    },
)
async def plot_sweep_svg(sweep_id: str, state: StateDep, caller: CallerDep) -> Response:
    return await _plot(sweep_id, state, "svg", caller.scope)


@job_handler("sweep-simulated")
def run_simulated_sweep_job(ctx: JobContext) -> dict[str, Any]:
    """A simulated early-warning sweep (``warn``)."""
    kwargs = {k: v for k, v in ctx.params.items() if v is not None}
    with as_problems("simulate"):
        res = warn(**kwargs, progress=ctx.progress)
    return convert.sweep_result(res).model_dump(mode="json")


@job_handler("sweep-signals")
def run_signal_sweep_job(ctx: JobContext) -> dict[str, Any]:
    """A sweep of stored recordings: detect each, then classify and predict."""
    params, progress, store = ctx.params, ctx.progress, ctx.store
    items, units, labels, metas = [], [], [], []
    quantities: list[str | None] = []
    for k, m in enumerate(params["measurements"]):
        sig = store.get_signal(m["signal_id"])
        if sig is None:
            raise ApiProblem(
                422,
                f"signal {m['signal_id']!r} was deleted",
                field=f"measurements[{k}].signal_id",
                value=m["signal_id"],
            )
        items.append((sig.w, float(sig.row.dt), float(m["control_value"])))
        units.append(sig.row.unit)
        quantities.append(recordings.quantity_of(sig.row.value_unit))
        labels.append(sig.row.name)
        metas.append((sig.row.meta or {}).get("recording_flags") or [])
        progress(0.1 * (k + 1) / len(params["measurements"]), "loading signals")
    progress(0.1, f"analysing {len(items)} signals")
    ids = [m["signal_id"] for m in params["measurements"]]
    names = record_names(labels, ids)  # set-aside reasons name the file, never an index or id
    notes = dict(zip(names, metas))
    # signals stored in different time units (one in ms, another in s) are brought to seconds
    try:
        factors, time_unit = recordings.common_time_base(units, names)
    except recordings.RecordingError as exc:
        raise ApiProblem(422, str(exc), field="measurements", value=exc.value) from None
    items = [(w, dt * f, c) for (w, dt, c), f in zip(items, factors)]
    # the lab options; a start in a signal's own time unit follows it to the common one
    options = []
    for m, f, q in zip(params["measurements"], factors, quantities, strict=True):
        opts = dict(m.get("options") or {})
        if "start" in opts:
            opts["start"] = float(opts["start"]) * f
        if q is not None:
            opts.setdefault("quantity", q)
        options.append(opts)
    band = params.get("band")
    with as_problems("measurements"):
        res = sweep_from_signals(
            items, names=names, progress=lambda f, msg: progress(0.1 + 0.9 * f, msg),
            options=options, plan=SweepPlan(band=tuple(band) if band else None),
            time_unit=time_unit,
        )  # fmt: skip
    doc = convert.sweep_result(res, record_flags=notes, time_unit=time_unit,
                               signal_ids=dict(zip(names, ids)))  # fmt: skip
    return doc.model_dump(mode="json")


def record_names(names: list[str | None], ids: list[str]) -> list[str]:
    """Each stored signal's record name: the name it was uploaded with (its file's), else its
    id; a name two signals share gets the signal's id beside it (one name, one record)."""
    base = [n or i for n, i in zip(names, ids, strict=True)]
    seen = {n: base.count(n) for n in base}
    return [n if seen[n] == 1 else f"{n} (signal {i})" for n, i in zip(base, ids, strict=True)]
