"""The one seam between the numerics' results and the wire models.

The numerics (``service.analysis``, ``sim``) return frozen dataclasses; the API, the CLI's
``--json`` and the SDK share the pydantic models of :mod:`service.schemas.analysis`,
:mod:`service.schemas.sim` and :mod:`service.schemas.snaps`. This module is the only place that
knows both: every document of a scientific result is built here, so that ``snapwarn sweep
--json``, ``snapwarn warn --json`` and ``/v1/sweeps`` print one document (and ``snapwarn snap
--json`` and ``/v1/snaps`` another).

Numbers that are missing or not finite become ``None`` (strict JSON). :data:`PARITY` lists, for
each result dataclass, its wire model and the fields deliberately left out; a test checks that
the two agree, so a field added to the numerics without its wire counterpart fails the tests
(and the OpenAPI drift test sees the models).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping
from typing import Any

from service.schemas import analysis as wire
from service.schemas import atlases as atlas_wire
from service.schemas import sim as sim_wire
from service.schemas import snaps as snap_wire

__all__ = [
    "PARITY",
    "alarm",
    "atlas_cell",
    "atlas_report",
    "atlas_summary",
    "backend_choice",
    "beam_summary",
    "bifurcation",
    "bifurcation_point",
    "equilibria",
    "equilibrium",
    "error_estimate",
    "classification",
    "detection",
    "flag",
    "flags",
    "live_update",
    "measurement",
    "mode",
    "normal_form",
    "paper_rule",
    "parity_problems",
    "plain",
    "prediction",
    "resolution",
    "simulation",
    "simulation_info",
    "simulation_info_problems",
    "snap",
    "spectrum",
    "sweep_document",
    "sweep_result",
]

#: result dataclass ("module:Name") -> (wire model, numerics fields not on the wire,
#: wire fields not on the dataclass). Checked by the tests in both directions.
PARITY: dict[str, tuple[type[wire.BaseModel], frozenset[str], frozenset[str]]] = {
    "service.analysis.common:Flag": (wire.Flag, frozenset(), frozenset()),
    "service.analysis.detect:Mode": (wire.Mode, frozenset(), frozenset()),
    # the record's units come from its reader (the file's header), not from the numerics
    "service.analysis.detect:Detection": (
        wire.Detection, frozenset(), frozenset({"time_unit", "value_unit"})
    ),
    "service.analysis.measurement:Measurement": (wire.Measurement, frozenset(), frozenset()),
    "service.analysis.predict:PaperRule": (wire.PaperRule, frozenset(), frozenset()),
    # the model fits are the engine's internals (profiles, windows): not a result
    "service.analysis.classify:Classification": (
        wire.Classification,
        frozenset({"fits"}),
        frozenset(),
    ),
    "service.analysis.alarm:Alarm": (wire.Alarm, frozenset(), frozenset()),
    "service.analysis.predict:Prediction": (wire.Prediction, frozenset(), frozenset()),
    "service.analysis.pipeline:WarnResult": (
        wire.SweepResult, frozenset(), frozenset({"n_set_aside"})
    ),
    "service.analysis.sweep_policy:SetAside": (wire.SetAside, frozenset(), frozenset()),
    # the simulator's results
    "sim.results:Resolution": (sim_wire.Resolution, frozenset(), frozenset()),
    "sim.results:BifurcationPoint": (sim_wire.BifurcationPoint, frozenset(), frozenset()),
    # w_star (the shape at mu*, rod only) and info (diagnostics) stay in the numerics;
    # mu_star_error and elements are the dataclass's properties (from its resolution)
    "sim.results:Bifurcation": (
        sim_wire.Bifurcation,
        frozenset({"w_star", "info"}),
        frozenset({"mu_star_error", "elements"}),
    ),
    # the scene (model, actuation, mu) and the resolution are the Equilibria document's
    "sim.results:EquilibriumSummary": (
        sim_wire.Equilibrium,
        frozenset({"model", "actuation", "mu", "resolution"}),
        frozenset(),
    ),
    "sim.results:SpectrumSummary": (sim_wire.Spectrum, frozenset(), frozenset({"omega"})),
    "sim.results:ErrorEstimate": (sim_wire.ErrorEstimate, frozenset(), frozenset({"total"})),
    "sim.select:Choice": (
        sim_wire.BackendChoice,
        frozenset({"estimate"}),
        frozenset({"error"}),
    ),
    # the atlas (the service's grid of cells)
    "service.atlas.cells:CellResult": (atlas_wire.AtlasCell, frozenset(), frozenset()),
    "service.atlas.results:AtlasSummary": (atlas_wire.AtlasSummary, frozenset(), frozenset()),
    "service.atlas.results:AtlasResult": (
        atlas_wire.AtlasReport,
        frozenset({"rows"}),
        frozenset({"cells"}),
    ),
    # phi0: the critical mode on the quadrature grid (an internal of the amplitude equation)
    "sim.normal_form:NormalForm": (sim_wire.NormalForm, frozenset({"phi0"}), frozenset()),
    "sim.snap:SnapResult": (
        snap_wire.SnapResult,
        frozenset({"info"}),
        frozenset({"samples", "duration"}),
    ),
}


def plain(value: Any) -> Any:
    """A result as plain JSON data: dataclasses as dicts (the simulator's typed results in a
    signal's ``info`` as their wire documents), non-finite floats as ``None``."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        typed = _TYPED.get(f"{type(value).__module__}:{type(value).__qualname__}")
        if typed is not None:
            return typed(value).model_dump(mode="json")
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int) and not hasattr(value, "dtype"):
        return value
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    kind = getattr(getattr(value, "dtype", None), "kind", None)
    if kind is not None and getattr(value, "ndim", 0) > 0:  # numpy array
        return [plain(v) for v in value.tolist()]
    if kind == "b":
        return bool(value)
    if kind in ("i", "u"):
        return int(value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        return value
    return v if math.isfinite(v) else None


def _fields(obj: Any, skip: Iterable[str] = ()) -> dict[str, Any]:
    """The dataclass fields of ``obj`` (not ``skip``), as plain data."""
    left_out = set(skip)
    return {
        f.name: plain(getattr(obj, f.name))
        for f in dataclasses.fields(obj)
        if f.name not in left_out
    }


# ------------------------------------------------------------------------------------ results
def flag(f: Any) -> wire.Flag:
    """A numerics ``Flag`` (or a ``{code, message}`` mapping)."""
    if isinstance(f, Mapping):
        return wire.Flag(code=str(f["code"]), message=str(f["message"]))
    return wire.Flag(code=f.code, message=f.message)


def flags(items: Iterable[Any]) -> list[wire.Flag]:
    """Flags in order, each code once (the first message kept)."""
    out: list[wire.Flag] = []
    seen: set[tuple[str, str]] = set()
    for f in items:
        w = flag(f)
        if (w.code, w.message) not in seen:
            seen.add((w.code, w.message))
            out.append(w)
    return out


def mode(m: Any) -> wire.Mode:
    """A detected ``Mode``."""
    return wire.Mode.model_validate(_fields(m))


def detection(
    det: Any,
    *,
    extra_flags: Iterable[Any] = (),
    control: float | None = None,
    name: str | None = None,
    time_unit: str | None = None,
    value_unit: str | None = None,
) -> wire.Detection:
    """A ``Detection``; ``extra_flags`` (e.g. the reader's) come first. With ``control`` or
    ``name``, a :class:`~service.schemas.analysis.RecordDetection` (a record of a sweep).
    ``time_unit``, ``value_unit``: the record's units as its file named them (the numbers are
    in them: omega in rad per ``time_unit``)."""
    if isinstance(det, Mapping):  # a document (the per-record detections of older sweeps)
        return _detection_doc(det, control, name)
    doc = _fields(det, skip=("modes", "fundamental", "flags"))
    modes = [mode(m) for m in det.modes]
    fund = None
    if det.fundamental is not None:
        i = int(det.fundamental.index)
        fund = wire.Fundamental(**modes[i].model_dump(), index=i)
    doc.update(modes=modes, fundamental=fund, flags=flags([*extra_flags, *det.flags]),
               time_unit=time_unit or None, value_unit=value_unit or None)  # fmt: skip
    if control is not None or name is not None:
        return wire.RecordDetection(**doc, control=plain(control), name=name)
    return wire.Detection(**doc)


def _detection_doc(doc: Mapping[str, Any], control: Any, name: str | None) -> wire.Detection:
    d = dict(doc)
    f, modes = d.get("fundamental"), d.get("modes") or []
    if isinstance(f, Mapping) and "frequency" not in f:  # older documents: a flat summary
        i = int(f.get("index") or 0)
        d["fundamental"] = {**modes[i], "index": i} if i < len(modes) else None
    if control is None and name is None and "control" not in d and "name" not in d:
        return wire.Detection.model_validate(d)
    d.setdefault("control", control)
    d.setdefault("name", name)
    return wire.RecordDetection.model_validate(d)


def measurement(m: Any) -> wire.Measurement:
    """A sweep's ``Measurement``."""
    return wire.Measurement.model_validate(_fields(m))


def paper_rule(p: Any) -> wire.PaperRule:
    """The paper's rule (``PaperRule``)."""
    return wire.PaperRule.model_validate(_fields(p))


def classification(c: Any) -> wire.Classification:
    """A ``Classification`` (without the engine's model fits)."""
    return wire.Classification.model_validate(_fields(c, skip=("fits",)))


#: alarm levels as stored, the current scale's and the former "none" (T/T0 <= 3: no judgement)
_LEVELS = {"insufficient": "insufficient", "clear": "clear", "watch": "watch",
           "warning": "warning", "critical": "critical", "none": "insufficient"}  # fmt: skip
_RANK = {name: i for i, name in enumerate(("insufficient", "clear", "watch", "warning",
                                           "critical"))}  # fmt: skip


def alarm(a: Any) -> wire.Alarm:
    """An ``Alarm`` (or an older alarm mapping, completed by the alarm rule)."""
    if isinstance(a, Mapping) and a.get("level") in _LEVELS:
        return wire.Alarm.model_validate(
            {**a, "level": _LEVELS[a["level"]], "rank": _RANK[_LEVELS[a["level"]]]}
            if a["level"] == "none" else a
        )
    if isinstance(a, Mapping):
        from service.analysis.alarm import alarm_for

        nan = math.nan
        lo, hi = a.get("mu_star_interval") or (nan, nan)
        mu_star = a.get("mu_star")
        a = alarm_for(
            float(a.get("mu", nan) if a.get("mu") is not None else nan),
            float(a.get("t_ratio", nan) if a.get("t_ratio") is not None else nan),
            float(mu_star) if mu_star is not None else nan,
            (float(lo if lo is not None else nan), float(hi if hi is not None else nan)),
        )
    return wire.Alarm.model_validate(_fields(a))


def prediction(p: Any) -> wire.Prediction:
    """A ``Prediction``, with its alarm, the paper's rule and the classification (a law of the
    caller's own exponent, ``predict(a=...)`` neither 1/4 nor 1/2: ``transition`` "custom",
    the exponent in ``a``)."""
    doc = _fields(p, skip=("alarm", "baseline", "classification", "flags"))
    return wire.Prediction(
        **doc,
        alarm=alarm(p.alarm) if p.alarm is not None else None,
        baseline=paper_rule(p.baseline) if p.baseline is not None else None,
        classification=classification(p.classification) if p.classification is not None else None,
        flags=flags(p.flags),
    )


def sweep_result(
    r: Any,
    *,
    record_flags: Mapping[str, Iterable[Any]] | None = None,
    time_unit: str | None = None,
    signal_ids: Mapping[str, str] | None = None,
) -> wire.SweepResult:
    """A sweep (``WarnResult``: simulated or recorded) as the one sweep document.

    ``record_flags``: per record name, what the reader noticed about the file (rounded
    timestamps, resampling), listed first among that record's detection flags.
    ``time_unit``: the records' common time unit (their detections are in it), if named.
    ``signal_ids``: per record name, its stored signal's id (a sweep of stored signals): the
    detection's ``name`` is then the signal id (pages link the record by it) and its
    ``record_name`` the record's name.
    """
    doc = _fields(r, skip=("measurements", "prediction", "alarm", "flags", "detections",
                           "set_aside"))  # fmt: skip
    dets = []
    for d in r.detections:
        if isinstance(d, Mapping):
            one = _detection_doc(d, d.get("control"), d.get("name"))
        else:  # a (detection, control, name) triple or a detection with those attributes
            det, control, label = d if isinstance(d, tuple) else (d, None, None)
            name = (signal_ids or {}).get(label or "", label)
            one = detection(det, control=control, name=name, time_unit=time_unit)
            if label is not None:
                one = one.model_copy(update={"record_name": label})
        notes = (record_flags or {}).get(getattr(one, "record_name", None)
                                         or getattr(one, "name", None) or "")  # fmt: skip
        if notes:
            one = one.model_copy(update={"flags": flags([*notes, *one.flags])})
        dets.append(one)
    return wire.SweepResult(
        **doc,
        measurements=[measurement(m) for m in r.measurements],
        prediction=prediction(r.prediction) if r.prediction is not None else None,
        alarm=[alarm(a) for a in r.alarm],
        flags=flags(r.flags),
        detections=dets,
        set_aside=[wire.SetAside.model_validate(_fields(a)) for a in r.set_aside],
        n_set_aside=len(r.set_aside),
    )


def sweep_document(doc: Mapping[str, Any]) -> wire.SweepResult:
    """A stored sweep document as the typed result: the current form, or the older flat one
    (written by the former ``WarnResult.to_dict()``: mu* at the top level, alarms without a
    level)."""
    d = dict(doc)
    d["alarm"] = [alarm(a) for a in (d.get("alarm") or []) if isinstance(a, Mapping)]
    if d.get("prediction") is None and d.get("mu_star_interval") is not None:
        keys = ("mu_star", "mu_star_interval", "mu_star_std", "a", "transition",
                "probabilities", "baseline", "classification")  # fmt: skip
        flat = {k: d[k] for k in keys if d.get(k) is not None}
        if isinstance(flat.get("classification"), Mapping):
            flat["classification"] = {"regime": "underdamped", **flat["classification"]}
        d["prediction"] = flat
    d.setdefault("stopped", "done")
    d["detections"] = [
        _detection_doc(x, x.get("control"), x.get("name"))
        for x in (d.get("detections") or [])
        if isinstance(x, Mapping)
    ]
    return wire.SweepResult.model_validate(d)


def live_update(
    u: Any,
    *,
    sweep_id: str | None = None,
    signal_id: str | None = None,
    created_at: Any = None,
    finished: bool = False,
    options: Mapping[str, Any] | None = None,
) -> Any:
    """A live sweep's update (``service.analysis.live.LiveUpdate``) as its wire model
    (:class:`service.schemas.live.LiveUpdate`); ``options``: the detector's options the record
    was read with."""
    from service.schemas.live import LiveUpdate, RecordOptions

    p, rec, nxt = u.prediction, u.record, u.next
    return LiveUpdate(
        sweep_id=sweep_id,
        seq=rec.seq,
        signal_id=signal_id,
        record_name=rec.name,
        control=rec.control,
        record_options=RecordOptions.model_validate(dict(options or {})),
        record_flags=flags(rec.flags),
        used_in_fit=u.used_in_fit,
        measurement=measurement(rec.measurement) if rec.measurement is not None else None,
        detection=detection(u.detection),
        n_records=u.n_records,
        n_used=u.n_used,
        transition=p.transition if p is not None else "undetermined",
        probabilities=plain(dict(p.probabilities)) if p is not None else {},
        mu_star=plain(p.mu_star) if p is not None else None,
        mu_star_interval=plain(tuple(p.mu_star_interval)) if p is not None else None,
        prediction=prediction(p) if p is not None else None,
        alarm=alarm(u.alarm),
        next_control=plain(rec.next_control),
        next_bound=plain(nxt.bound) if nxt is not None else None,
        next_bound_source=nxt.source if nxt is not None else "none",
        next_limited_by=nxt.limited_by if nxt is not None else "no_advice",
        trusted=u.trusted,
        converged=u.converged,
        record_duration=plain(u.record_duration),
        record_dt=plain(u.record_dt),
        flags=flags(u.flags),
        set_aside=[wire.SetAside.model_validate(_fields(a)) for a in u.set_aside],
        n_set_aside=len(u.set_aside),
        record_advice=u.record_advice,
        finished=finished,
        created_at=created_at,
    )


# ------------------------------------------------------------------------------ simulator
def resolution(r: Any) -> sim_wire.Resolution:
    """The discretisation of a result (``sim.results.Resolution``)."""
    return sim_wire.Resolution.model_validate(_fields(r))


def _resolution_or_none(r: Any) -> sim_wire.Resolution | None:
    return None if r is None else resolution(r)


def bifurcation_point(p: Any) -> sim_wire.BifurcationPoint:
    """A secondary bifurcation (``sim.results.BifurcationPoint``)."""
    return sim_wire.BifurcationPoint.model_validate(_fields(p))


def bifurcation(b: Any) -> sim_wire.Bifurcation:
    """The transition of U_A (``sim.results.Bifurcation``); the strip's fields are null for
    the backends without one (all but the Cosserat rod)."""
    doc = _fields(b, skip=("secondary", "resolution", "w_star", "info", "end_shortening",
                           "slenderness"))  # fmt: skip
    rod = b.model == "cosserat"
    return sim_wire.Bifurcation(
        **doc,
        secondary=[bifurcation_point(s) for s in b.secondary],
        mu_star_error=plain(b.mu_star_error),
        resolution=_resolution_or_none(b.resolution),
        elements=b.elements,
        end_shortening=plain(b.end_shortening) if rod else None,
        slenderness=plain(b.slenderness) if rod else None,
    )


def equilibrium(e: Any) -> sim_wire.Equilibrium:
    """One equilibrium (``sim.results.EquilibriumSummary``)."""
    return sim_wire.Equilibrium.model_validate(
        _fields(e, skip=("model", "actuation", "mu", "resolution"))
    )


def equilibria(eqs: Iterable[Any], *, actuation: str, mu: float, model: str) -> sim_wire.Equilibria:
    """Every equilibrium of a scene; the resolution is the first one's (one scene, one
    resolution)."""
    items = list(eqs)
    res = items[0].resolution if items else None
    return sim_wire.Equilibria(actuation=actuation, mu=plain(mu), model=model,
                               equilibria=[equilibrium(e) for e in items],
                               resolution=_resolution_or_none(res))  # fmt: skip


def spectrum(s: Any) -> sim_wire.Spectrum:
    """A linear spectrum (``sim.results.SpectrumSummary``) with omega = sqrt|sigma^2|."""
    doc = _fields(s, skip=("resolution",))
    res = _resolution_or_none(s.resolution)
    return sim_wire.Spectrum(**doc, omega=plain(s.omega), resolution=res)


def error_estimate(e: Any) -> sim_wire.ErrorEstimate:
    """A backend's estimated relative error (``sim.results.ErrorEstimate``) and its total."""
    return sim_wire.ErrorEstimate(**_fields(e), total=plain(e.total))


def backend_choice(c: Any) -> sim_wire.BackendChoice:
    """What ``model="auto"`` picked (``sim.select.Choice``)."""
    doc = _fields(c, skip=("estimate",))
    return sim_wire.BackendChoice(**doc, error=error_estimate(c.estimate))


def normal_form(nf: Any) -> sim_wire.NormalForm:
    """The amplitude equation's coefficients (``sim.normal_form.NormalForm``)."""
    return sim_wire.NormalForm.model_validate(_fields(nf, skip=("phi0",)))


def simulation_info(info: Mapping[str, Any]) -> sim_wire.SimulationInfo:
    """What a backend reports about a simulation (``sim.scene.Signal.info``): its
    ``Resolution``, ``ErrorEstimate`` and (``model="auto"``) ``Choice`` typed, its own numbers
    as plain data (a key without a wire field is left out: see
    :func:`simulation_info_problems`)."""
    typed = {"resolution": resolution, "error": error_estimate, "auto": backend_choice}
    doc = {
        str(k): typed[k](v) if k in typed and dataclasses.is_dataclass(v) else plain(v)
        for k, v in info.items()
    }
    return sim_wire.SimulationInfo.model_validate(doc)


def simulation_info_problems(info: Mapping[str, Any]) -> list[str]:
    """The keys of a simulation's ``info`` that :class:`~service.schemas.sim.SimulationInfo`
    has no field for (empty when the wire carries all of it)."""
    wire_keys = {f.alias or name for name, f in sim_wire.SimulationInfo.model_fields.items()}
    return [f"info[{k!r}] has no field in SimulationInfo (add it)"
            for k in sorted(map(str, info)) if k not in wire_keys]  # fmt: skip


def simulation(sig: Any, *, path: str) -> sim_wire.Simulation:
    """A simulated signal (``sim.scene.Signal``) written to ``path``: its scene, sampling and
    the resolution, error estimate and (``model="auto"``) choice in its ``info`` (as
    :func:`simulation_info` types them)."""
    info, scene = simulation_info(sig.info), sig.scene
    return sim_wire.Simulation(
        path=path, samples=int(sig.t.size), model=sig.model, actuation=scene.actuation,
        mu=plain(scene.mu), branch=scene.branch, dt=plain(sig.dt),
        duration=plain(sig.t[-1]) if sig.t.size else None, w_static=plain(sig.w_static),
        sigma2=info.sigma2[0] if info.sigma2 else None, resolution=info.resolution,
        error=info.error, auto=info.auto,
    )  # fmt: skip


def beam_summary(
    transitions: Iterable[Any], spectra: Iterable[tuple[str, float, Any]], signal: Any
) -> sim_wire.BeamSummary:
    """The demo's beam in brief: the ``Bifurcation`` of each actuation, ``(actuation, mu,
    sigma2)`` of U_A at a few mu, and one simulated ``Signal`` summarised."""
    info = signal.info
    return sim_wire.BeamSummary(
        transitions=[bifurcation(b) for b in transitions],
        spectrum_U_A=[sim_wire.SpectrumPoint(actuation=a, mu=plain(mu), sigma2=plain(s2))
                      for a, mu, s2 in spectra],
        impulse_response=sim_wire.ImpulseResponseSummary(
            actuation=signal.scene.actuation, mu=plain(signal.scene.mu),
            samples=int(signal.t.size), dt=plain(signal.dt), w_static=plain(signal.w_static),
            w_min=plain(signal.w.min()), w_max=plain(signal.w.max()),
            sigma2=plain((info.get("sigma2") or [None])[0]),
        ),
    )  # fmt: skip


def snap(r: Any, *, path: str | None = None) -> snap_wire.SnapResult:
    """A snap-through (``sim.snap.SnapResult``) with its record; with ``path`` (the CSV
    written) the CLI's :class:`~service.schemas.snaps.SnapReport`."""
    doc = _fields(r, skip=("t", "amplitude", "resolution", "info"))
    doc.update(
        samples=int(r.t.size),
        duration=float(r.t[-1]) if r.t.size else 0.0,
        t=plain(r.t),
        amplitude=plain(r.amplitude),
        resolution=_resolution_or_none(r.resolution),
    )
    if path is not None:
        return snap_wire.SnapReport(**doc, path=path)
    return snap_wire.SnapResult(**doc)


# ---------------------------------------------------------------------------------- atlas
def atlas_cell(row: Any) -> atlas_wire.AtlasCell:
    """One finished cell of an atlas (``service.atlas.CellResult``): the row the CLI prints,
    ``cells.jsonl`` holds and ``/v1/atlases/{id}/cells`` pages."""
    return atlas_wire.AtlasCell.model_validate(_fields(row))


def atlas_summary(s: Any) -> atlas_wire.AtlasSummary:
    """An atlas's counts, cost and headline numbers (``service.atlas.AtlasSummary``)."""
    return atlas_wire.AtlasSummary.model_validate(_fields(s))


def atlas_report(r: Any) -> atlas_wire.AtlasReport:
    """An atlas run (``service.atlas.AtlasResult``): ``snapwarn atlas --json``."""
    return atlas_wire.AtlasReport(
        name=r.name, kind=r.kind, varied=list(r.varied), summary=atlas_summary(r.summary),
        cells=[atlas_cell(row) for row in r.rows], missing=list(r.missing),
    )  # fmt: skip


_TYPED: dict[str, Any] = {
    "sim.results:Resolution": resolution,
    "sim.results:ErrorEstimate": error_estimate,
    "sim.select:Choice": backend_choice,
}


def parity_problems() -> list[str]:
    """Where a result dataclass and its wire model disagree (see :data:`PARITY`); empty when
    every numerics field has its wire field and every wire field its numerics source."""
    import importlib

    out = []
    for where, (model, left_out, wire_only) in PARITY.items():
        module, name = where.split(":")
        cls = getattr(importlib.import_module(module), name)
        fields = {f.name for f in dataclasses.fields(cls)}
        wire_fields = set(model.model_fields)
        for f in sorted(fields - left_out - wire_fields):
            out.append(f"{where}.{f} has no field in {model.__name__} (add it, or list it)")
        for f in sorted(wire_fields - wire_only - fields):
            out.append(f"{model.__name__}.{f} has no source in {where}")
        for f in sorted(left_out - fields):
            out.append(f"{where}: PARITY leaves out {f!r}, which it does not have")
    return out
