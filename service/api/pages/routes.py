"""The page routes: ``/``, ``/sweeps/{id}``, ``/signals/{id}``, ``/jobs/{id}``, ``/login``.

Each page reads the same rows as the API (the store, scoped to the caller) and the same
documents (``sweep_doc``, ``job_doc``); charts are drawn in the analysis pool.
"""

from __future__ import annotations

import json
import math
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Annotated, Any
from urllib.parse import quote

import jinja2
from anyio import to_thread
from fastapi import APIRouter, Form, Query, Request, Response
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse
from fastapi.templating import Jinja2Templates

from service import numfmt
from service.api.auth import Caller, get_caller
from service.api.live_events import event_stream
from service.api.pages import _work
from service.api.problems import ApiProblem
from service.api.state import AppState, get_state, job_doc, signal_meta
from service.api.sweep_views import sweep_doc, sweep_units
from service.charts import MEDIA
from service.convert import sweep_document
from service.schemas import Sweep
from service.schemas.analysis import SweepResult

HERE = Path(__file__).parent
COOKIE = "snapwarn_session"
RECENT = 20
#: A page's event stream ends after this long (s); the browser reconnects where it left off.
EVENTS_TIMEOUT_S = 300.0
#: The largest record number a page's query may name.
MAX_SEQ = 2**31 - 1

router = APIRouter(include_in_schema=False)
templates = Jinja2Templates(directory=HERE / "templates")


def _num(x: Any, digits: int = 6) -> str:
    """A number for a page: ``-`` when missing or not finite."""
    if x is None:
        return "-"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(v):
        return "-"
    return f"{v:.{digits}g}"


def _val(x: Any) -> str:
    """A value as JSON text for a ``data-value`` attribute (escaped by the template): what the
    API answers for the same field (``null`` for missing and non-finite numbers)."""
    if isinstance(x, jinja2.Undefined) or x is None:
        return "null"
    if isinstance(x, float) and not math.isfinite(x):
        return "null"
    return json.dumps(x)


templates.env.filters["num"] = _num
# numbers as a scientist writes them (service.numfmt): rounded to their uncertainty
templates.env.filters["unc"] = lambda x, u=None: numfmt.fmt(x, u)
templates.env.filters["below"] = lambda x, u=None: numfmt.fmt_below(x, u)
templates.env.filters["pm"] = lambda x, u=None: numfmt.fmt_pm(x, u)
templates.env.filters["lo"] = lambda iv: numfmt.fmt_interval(iv[0], iv[1])[0]
templates.env.filters["hi"] = lambda iv: numfmt.fmt_interval(iv[0], iv[1])[1]
templates.env.filters["hz"] = lambda omega, unit=None: numfmt.hz(omega, unit) or ""
templates.env.filters["uniq"] = lambda fl: _unique_flags(fl)


def _unique_flags(flags: Any) -> list[Any]:
    """Flags in order, each (code, message) once: a sweep's flags and its prediction's overlap."""
    seen, out = set(), []
    for f in flags or ():
        key = (getattr(f, "code", None), getattr(f, "message", None))
        if key not in seen:
            seen.add(key)
            out.append(f)
    return out
templates.env.filters["val"] = _val
templates.env.filters["pct"] = lambda x: f"{100 * float(x or 0):.0f} %"


# ------------------------------------------------------------------------------ the caller
#: Lifetime of a page session (seconds).
SESSION_TTL_S = 12 * 3600.0


async def page_caller(request: Request) -> Caller | None:
    """The caller, as the API sees it (a key in a header), else the page session's (the
    cookie's random token, looked up by its digest); None when a key is needed and there is
    neither."""
    token = request.cookies.get(COOKIE)
    has_header = request.headers.get("authorization") or request.headers.get("x-api-key")
    st = getattr(request.app.state, "snapwarn", None)
    if token and not has_header and st is not None:
        found = await to_thread.run_sync(st.store.session_caller, token)
        if found is not None:
            return Caller(owner=found[0], admin=found[1], key_id=found[2])
    try:
        return await get_caller(request)
    except ApiProblem as exc:
        if exc.status == 401:
            return None
        raise


def _page(
    request: Request, template: str, context: dict[str, Any], status: int = 200
) -> HTMLResponse:
    return templates.TemplateResponse(request, template, context, status_code=status)


def _error(request: Request, status: int, detail: str) -> HTMLResponse:
    return _page(request, "error.html", {"status": status, "detail": detail}, status)


def _login(request: Request) -> HTMLResponse:
    nxt = request.url.path
    return _page(request, "login.html", {"next": nxt, "failed": False}, 401)


Handler = Callable[[Caller, AppState], Awaitable[Response]]


async def _serve(request: Request, handler: Handler) -> Response:
    """Resolve the caller (login page when needed), run ``handler``, map problems to pages."""
    try:
        state = get_state(request)
        caller = await page_caller(request)
        if caller is None:
            return _login(request)
        return await handler(caller, state)
    except ApiProblem as exc:
        return _error(request, exc.status, exc.detail)


# ------------------------------------------------------------------------------ login
@router.get("/login", response_class=HTMLResponse)
async def login_form(request: Request, next: str = "/") -> HTMLResponse:
    return _page(request, "login.html", {"next": _safe_next(next), "failed": False})


def _safe_next(nxt: str) -> str:
    """Only a path on this server (no scheme, no host) is followed after login."""
    return nxt if nxt.startswith("/") and not nxt.startswith("//") else "/"


@router.post("/login", response_class=HTMLResponse)
async def login(request: Request, key: str = Form(...), next: str = Form("/")) -> Response:
    scope = dict(request.scope)
    scope["headers"] = [
        (k, v) for k, v in request.scope["headers"] if k not in (b"authorization", b"x-api-key")
    ] + [(b"authorization", f"Bearer {key}".encode("latin-1", "replace"))]
    try:
        caller = await get_caller(Request(scope))
    except ApiProblem:
        return _page(request, "login.html", {"next": _safe_next(next), "failed": True}, 401)
    st = request.app.state.snapwarn
    token = await to_thread.run_sync(
        st.store.create_session, caller.owner, caller.admin, caller.key_id, SESSION_TTL_S
    )  # the cookie holds a random session token (stored as its digest), never the key
    resp = RedirectResponse(_safe_next(next), status_code=303)
    resp.set_cookie(COOKIE, token, httponly=True, samesite="strict", path="/",
                    secure=_tls(request), max_age=int(SESSION_TTL_S))  # fmt: skip
    return resp


def _tls(request: Request) -> bool:
    """Whether the page is served over TLS: directly (``https``) or behind a TLS proxy
    (``X-Forwarded-Proto: https`` or ``Forwarded: proto=https``)."""
    if request.url.scheme == "https":
        return True
    if request.headers.get("x-forwarded-proto", "").split(",")[0].strip().lower() == "https":
        return True
    return "proto=https" in request.headers.get("forwarded", "").lower()


@router.post("/logout")
async def logout(request: Request) -> Response:
    token = request.cookies.get(COOKIE)
    st = getattr(request.app.state, "snapwarn", None)
    if token and st is not None:
        await to_thread.run_sync(st.store.end_session, token)
    resp = RedirectResponse("/login", status_code=303)
    resp.delete_cookie(COOKIE, path="/")
    return resp


# ------------------------------------------------------------------------------ index
@router.get("/", response_class=HTMLResponse)
async def index(request: Request) -> Response:
    async def handler(caller: Caller, state: AppState) -> Response:
        store, scope = state.store, caller.scope
        signals, n_signals = await to_thread.run_sync(
            lambda: store.list_signals(RECENT, 0, scope=scope)
        )
        sweeps, n_sweeps = await to_thread.run_sync(
            lambda: store.list_sweeps(RECENT, 0, scope=scope)
        )
        jobs, n_jobs = await to_thread.run_sync(
            lambda: store.list_jobs(None, None, RECENT, 0, scope=scope)
        )
        atlases, n_atlases = await to_thread.run_sync(lambda: _atlases(store, scope))
        ctx = {
            "caller": caller,
            "signals": [signal_meta(r) for r in signals],
            "n_signals": n_signals,
            "sweeps": [_sweep_row(s, j) for s, j in sweeps],
            "n_sweeps": n_sweeps,
            "jobs": [job_doc(j) for j in jobs],
            "n_jobs": n_jobs,
            "atlases": atlases,
            "n_atlases": n_atlases,
        }
        return _page(request, "index.html", ctx)

    return await _serve(request, handler)


def _sweep_row(sweep: Any, job: Any) -> dict[str, Any]:
    p = Sweep.model_validate(sweep_doc(sweep, job)).prediction
    return {
        "id": sweep.id,
        "name": sweep.name,
        "status": job.status,
        "transition": p.transition if p else None,
        "mu_star": p.mu_star if p else None,
        "created_at": sweep.created_at,
    }


def _atlases(store: Any, scope: str | None) -> tuple[list[dict[str, Any]], int]:
    """The caller's recent atlases (none where this installation has no atlas store)."""
    try:
        from service.api.storage import atlases as atlas_store
    except ImportError:
        return [], 0
    rows, total = atlas_store.list_atlases(store, RECENT, 0, scope=scope)
    return [
        {"id": a.id, "name": a.name, "kind": a.kind, "status": job.status, "done": done,
         "total": a.cells_total, "created_at": a.created_at}
        for a, job, done in rows
    ], total  # fmt: skip


# ------------------------------------------------------------------------------ jobs
def _job_view(job: Any) -> dict[str, Any]:
    doc = job_doc(job)
    link = None
    if job.kind.startswith("sweep"):
        link = f"/sweeps/{job.id}"
    return {**doc, "page_link": link, "done": job.status in ("succeeded", "failed", "cancelled")}


@router.get("/jobs/{job_id}", response_class=HTMLResponse)
async def job_page(request: Request, job_id: str) -> Response:
    async def handler(caller: Caller, state: AppState) -> Response:
        job = await to_thread.run_sync(lambda: state.store.get_job(job_id, scope=caller.scope))
        if job is None:
            return _error(request, 404, f"no job {job_id!r}")
        return _page(request, "job.html", {"job": _job_view(job), "caller": caller})

    return await _serve(request, handler)


@router.get("/jobs/{job_id}/status.json")
async def job_status(request: Request, job_id: str) -> Response:
    """What the job page polls (the page's own cookie works here, unlike on /v1)."""

    async def handler(caller: Caller, state: AppState) -> Response:
        job = await to_thread.run_sync(lambda: state.store.get_job(job_id, scope=caller.scope))
        if job is None:
            return JSONResponse({"detail": f"no job {job_id!r}"}, status_code=404)
        d = job_doc(job)
        return JSONResponse(
            {"status": d["status"], "progress": d["progress"], "done": _job_view(job)["done"]}
        )

    return await _serve(request, handler)


# ------------------------------------------------------------------------------ signals
async def _load_signal(state: AppState, caller: Caller, signal_id: str) -> Any:
    sig = await to_thread.run_sync(lambda: state.store.get_signal(signal_id, scope=caller.scope))
    if sig is None:
        raise ApiProblem(404, f"no signal {signal_id!r}")
    return sig


@router.get("/signals/{signal_id}", response_class=HTMLResponse)
async def signal_page(request: Request, signal_id: str) -> Response:
    async def handler(caller: Caller, state: AppState) -> Response:
        sig = await _load_signal(state, caller, signal_id)
        row = sig.row
        meta = signal_meta(row)
        try:
            det, svg = await state.run(
                _work.signal_analysis, sig.t, row.n, row.dt, row.t0, sig.w,
                row.unit, row.value_unit, row.name or row.id,
            )  # fmt: skip
        except ValueError as exc:  # the detector's validation (too short, constant...)
            det, svg = None, None
            meta["analysis_error"] = str(exc)
        modes = []
        for k, m in enumerate((det or {}).get("modes", [])):
            modes.append({"k": k + 1, **m, "period": _work.period(m.get("sigma2"))})
        ctx = {
            "caller": caller,
            "signal": meta,
            "detection": det,
            "modes": modes,
            "chart": _work.inline_svg(svg) if svg else None,
        }
        return _page(request, "signal.html", ctx)

    return await _serve(request, handler)


# ------------------------------------------------------------------------------ sweeps
def _records(result: SweepResult | None) -> list[dict[str, Any]]:
    """One row per record: the stored detections (recorded sweeps) or the measurements."""
    if result is None:
        return []
    rows = []
    if result.detections:
        for k, d in enumerate(result.detections):
            f = d.fundamental
            rows.append({
                "k": k,
                "control": d.control,
                "signal_id": d.name,
                "sigma2": f.sigma2 if f else None,
                "sigma2_std": f.sigma2_std if f else None,
                "period": _work.period(f.sigma2 if f else None),
                "omega": math.sqrt(-f.sigma2) if f and f.sigma2 is not None and f.sigma2 < 0
                else None,
                "regime": f.regime if f else None,
                "w_static": d.static_level,
                "flags": d.flags,
                "thumbnail": bool(d.name),
                "record_name": getattr(d, "record_name", None),
            })  # fmt: skip
        return rows
    for k, m in enumerate(result.measurements):
        rows.append({
            "k": k,
            "control": m.mu,
            "signal_id": None,
            "sigma2": m.sigma2,
            "sigma2_std": m.sigma2_std,
            "period": _work.period(m.sigma2),
            "omega": m.omega,
            "regime": m.regime,
            "w_static": m.w_static,
            "flags": m.flags,
            "thumbnail": False,
        })  # fmt: skip
    return rows


def _record_options(request: dict[str, Any], result: SweepResult | None,
                    updates: list[Any]) -> list[str]:  # fmt: skip
    """Per record (the rows of :func:`_records`) the options it was read with, as text: a live
    record's stored options; a batch record's from its request entry (by its signal id) and
    the sweep's notch; with the quantity the detection says."""
    if result is None or not result.detections:
        return []
    given: dict[str, dict[str, Any]] = {}
    for m in request.get("measurements") or []:
        if isinstance(m, dict) and m.get("signal_id"):
            given[m["signal_id"]] = m
    out = []
    for k, d in enumerate(result.detections):
        if updates and k < len(updates):
            o = updates[k].record_options.model_dump()
        else:
            o = dict(given.get(getattr(d, "name", None) or "", {}))
            o.setdefault("notch", request.get("notch"))
        parts = [str(o.get("quantity") or d.quantity)]
        if o.get("start") is not None:
            parts.append(f"start {o['start']:g}")
        if o.get("notch"):
            parts.append("notch " + ", ".join(f"{f:g}" for f in o["notch"]))
        if o.get("exclude"):
            parts.append("excluded by the user")
        out.append("; ".join(parts))
    return out


def _sweep_options(request: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The sweep's options as (label, key, text): given ones, else what the default does
    (none for a simulated sweep)."""
    if request.get("simulate") is not None:
        return []
    band, notch = request.get("band"), request.get("notch")
    rows = [
        ("fundamental's band of sqrt|sigma^2|", "band",
         f"[{band[0]:g}, {band[1]:g}] rad per time unit" if band
         else "none given: the mode that softens continuously across the sweep"),
        ("notch frequencies", "notch",
         ", ".join(f"{f:g}" for f in notch) + " cycles per time unit" if notch
         else "none given: lines before the kick or not decaying are found"),
    ]  # fmt: skip
    if request.get("mode") == "live":
        live = request.get("live") or {}
        defaults = {
            "step": "the largest step between the records so far",
            "margin": "0",
            "target_width": "1e-6 of max(|mu*|, span of the controls)",
            "control_resolution": "the decimals of the controls, at least 1e-4 of the step",
            "budget": "none",
            "method": "auto",
        }
        for key, default in defaults.items():
            v = live.get(key)
            text = default if v is None else (f"{v:g}" if isinstance(v, float) else str(v))
            rows.append((key.replace("_", " "), key, text))
    return rows


def _live_updates(store: Any, sweep_id: str) -> list[Any]:
    """The updates of a live sweep (typed), in arrival order; [] for other sweeps."""
    try:
        from service.api.storage import live as store_live
        from service.schemas.live import LiveUpdate
    except ImportError:
        return []
    row, recs = store_live.records_after(store, sweep_id, 0, 1000)
    if row is None:
        return []
    return [LiveUpdate.model_validate(r.doc) for r in recs]


def _live_result(updates: list[Any]) -> SweepResult | None:
    """An open live sweep seen as a sweep result: the measurements the fit used, the latest
    prediction and alarm, and each record's detection (stored records carry their id)."""
    if not updates:
        return None
    last = updates[-1]
    dets = []
    for u in updates:
        d = u.detection.model_dump()
        d.update(
            control=u.control,
            name=u.signal_id,
            record_name=u.record_name,
            flags=[f.model_dump() for f in (*u.record_flags, *u.detection.flags)],
        )
        dets.append(d)
    return SweepResult.model_validate({
        "measurements": [u.measurement.model_dump() for u in updates
                         if u.used_in_fit and u.measurement is not None],
        "prediction": last.prediction.model_dump() if last.prediction is not None else None,
        "alarm": [last.alarm.model_dump()],
        "stopped": "open",
        "flags": [f.model_dump() for f in last.flags],
        "detections": dets,
    })  # fmt: skip


async def _get_sweep(state: AppState, caller: Caller, sweep_id: str) -> tuple[Any, Any]:
    found = await to_thread.run_sync(lambda: state.store.get_sweep(sweep_id, scope=caller.scope))
    if found is None:
        raise ApiProblem(404, f"no sweep {sweep_id!r}")
    return found


@router.get("/sweeps/{sweep_id}", response_class=HTMLResponse)
async def sweep_page(request: Request, sweep_id: str) -> Response:
    async def handler(caller: Caller, state: AppState) -> Response:
        sweep, job = await _get_sweep(state, caller, sweep_id)
        doc = Sweep.model_validate(sweep_doc(sweep, job))
        units = await sweep_units(state, caller.scope, sweep)
        result, updates = doc.result, []
        if result is None and job.status == "open":  # a live sweep: its latest update
            updates = await to_thread.run_sync(lambda: _live_updates(state.store, sweep.id))
            result = _live_result(updates)
        p = result.prediction if result is not None else None
        chart = None
        if result is not None and result.measurements and p is not None:
            chart = await state.run(
                _work.sweep_svg, result.model_dump(mode="json"), units["control_name"],
                units["control_unit"], units["time_unit"], sweep.name or sweep.id,
            )  # fmt: skip
        next_value = updates[-1].next_control if updates else (p.next_safe_mu if p else None)
        ctx = {
            "caller": caller,
            "sweep": doc,
            "result": result,
            "p": p,
            "alarm": result.alarm[-1] if result is not None and result.alarm else doc.alarm,
            "next_value": next_value,
            "live_open": job.status == "open",
            "n_updates": updates[-1].seq if updates else 0,
            "job": _job_view(job),
            "units": units,
            "records": _records(result),
            "record_options": _record_options(sweep.request or {}, result, updates),
            "options": _sweep_options(sweep.request or {}),
            "chart": chart,
        }
        return _page(request, "sweep.html", ctx)

    return await _serve(request, handler)


@router.get("/sweeps/{sweep_id}/events")
async def sweep_events(
    request: Request,
    sweep_id: str,
    after: Annotated[int, Query(ge=0, le=MAX_SEQ)] = 0,
) -> Response:
    """What a live sweep's page follows: the server-sent events of ``/v1/sweeps/{id}/events``
    (an ``update`` per record after ``after``, then ``closed``), for the page's own cookie
    (an ``EventSource`` sends no ``Authorization`` header)."""

    async def handler(caller: Caller, state: AppState) -> Response:
        from service.api.storage import live as store_live

        row = await to_thread.run_sync(store_live.get_live, state.store, sweep_id, caller.scope)
        if row is None:
            return JSONResponse({"detail": f"no live sweep {sweep_id!r}"}, status_code=404)
        resume = request.headers.get("last-event-id")  # the browser's reconnection
        return event_stream(request, state, sweep_id, after, resume, EVENTS_TIMEOUT_S,
                            caller.key_id or caller.owner)  # fmt: skip

    return await _serve(request, handler)


@router.get("/sweeps/{sweep_id}/records/{k}.svg")
async def sweep_record_thumbnail(request: Request, sweep_id: str, k: int) -> Response:
    """Record ``k`` of a lab sweep with the detector's fit (stored detection) over it."""

    async def handler(caller: Caller, state: AppState) -> Response:
        sweep, job = await _get_sweep(state, caller, sweep_id)
        dets = []
        if job.status == "succeeded" and job.result:
            dets = sweep_document(job.result).detections
        elif job.status == "open":
            live = _live_result(await to_thread.run_sync(
                lambda: _live_updates(state.store, sweep.id)))  # fmt: skip
            dets = live.detections if live is not None else []
        if not 0 <= k < len(dets) or not dets[k].name:
            raise ApiProblem(404, f"sweep {sweep_id!r} has no stored record {k}")
        sig = await _load_signal(state, caller, dets[k].name)
        row = sig.row
        body = await state.run(
            _work.record_thumbnail, sig.t, row.n, row.dt, row.t0, sig.w, dets[k],
            row.unit, row.value_unit,
        )  # fmt: skip
        return Response(body, media_type=MEDIA["svg"])

    return await _serve(request, handler)


def quote_path(s: str) -> str:
    return quote(s, safe="")


templates.env.filters["q"] = quote_path
