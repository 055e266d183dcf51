"""Analysis commands: detect, predict, warn, sweep, and the demo (the main job).

Imports of the numerics, the wire models and the charts live in the command that uses them:
building the parser (every command, ``--help``) imports none of them.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from service.cli._common import (
    CliError,
    add_json_flag,
    add_plot_flag,
    bad,
    emit,
    error_from,
    finite,
)  # fmt: skip
from service.cli._progress import Progress, warm_kernels
from service.cli._vocab import PREDICT_TRANSITIONS, RECORDING_FORMATS

if TYPE_CHECKING:  # the parser is built without numpy; each command imports what it runs
    import numpy as np


# ------------------------------------------------------------------------------- file readers
def read_record(
    path: str,
    option: str = "FILE",
    *,
    dt: float | None = None,
    resample: bool = False,
    reader: dict[str, Any] | None = None,
) -> Any:
    """Read a record with :mod:`service.recordings`: the API's reader and rules.

    ``dt`` supplies the step of a file without times (1-D .npy, one-column CSV) and is an error
    for a file that has them; the uniform-sampling tolerance is ``SNAPWARN_UNIFORM_RTOL``.
    ``reader``: the upload's other fields (``fmt``, ``column``, ``time_column``, ``channel``).
    """
    from service.recordings import RecordingError, read_file

    opts = {k: v for k, v in (reader or {}).items() if v is not None}
    try:
        return read_file(path, dt=dt, resample=resample, **opts)
    except RecordingError as exc:
        err = error_from(exc, context=f"{option} {path!r}")
        assert err is not None
        raise err from None


def _read_table(path: str, option: str) -> Any:
    """A table (sweep, manifest) read by :func:`service.recordings.read_table`: the text rules
    of the recordings' CSV (BOM, UTF-16, comments, ``;``/tab, units in the header)."""
    from service.recordings import RecordingError, read_table

    p = Path(path)
    if not p.is_file():
        raise bad(option, path, "is not a readable file")
    try:
        return read_table(p.read_bytes(), what="file")
    except RecordingError as exc:
        err = error_from(exc, context=f"{option} {path!r}")
        assert err is not None
        raise err from None


def _floats(table: Any, name: str, option: str, path: str) -> np.ndarray:
    from service.recordings import RecordingError

    try:
        return table.floats(name, what="file")
    except RecordingError as exc:
        err = error_from(exc, context=f"{option} {path!r}")
        assert err is not None
        raise err from None


def _rate_column(
    table: Any, name: str, option: str, path: str, like: str | None = None
) -> np.ndarray:
    """A rate column (omega, omega_std) in rad/time: a header unit Hz, kHz, MHz or rpm is
    converted (``2 pi f``; the time unit is then the second), by the table the API's
    ``omega_unit`` uses (:data:`service.schemas.predictions.OMEGA_UNIT_FACTORS`). A column
    without a unit takes that of the column ``like`` (``omega_std`` is in the unit of ``omega``
    unless its header says otherwise)."""
    from service.schemas.predictions import OMEGA_UNIT_FACTORS

    v = _floats(table, name, option, path)
    unit = (table.units.get(name) or (table.units.get(like) if like else None) or "").lower()
    factors = {u.lower(): f for u, f in OMEGA_UNIT_FACTORS.items()}
    return v * factors[unit] if unit in factors else v


#: Column names read as the fundamental's frequency f (Hz unless the header names another
#: unit of :data:`service.schemas.predictions.OMEGA_UNIT_FACTORS`) or its period T, when the
#: table has neither sigma2 nor omega: omega = 2 pi f, or 2 pi / T (in rad per T's unit).
_FREQUENCY_NAMES = ("frequency", "freq", "f")
_PERIOD_NAMES = ("period",)


def _rates_from_f_or_t(table: Any, path: str) -> dict[str, np.ndarray]:
    """``omega`` (and ``omega_std``) of a table that gives the fundamental's frequency or its
    period instead (see :data:`_FREQUENCY_NAMES`); empty when it gives neither."""
    from service.schemas.predictions import OMEGA_UNIT_FACTORS

    out: dict[str, np.ndarray] = {}
    f_col = table.find(*_FREQUENCY_NAMES)
    if f_col is not None:
        factors = {u.lower(): v for u, v in OMEGA_UNIT_FACTORS.items()}
        unit = (table.units.get(f_col) or "hz").lower()
        k = factors.get(unit, 2.0 * math.pi)  # a frequency: cycles per time unit
        out["omega"] = k * _floats(table, f_col, "SWEEP", path)
        sd = table.find(*(f"{n}_std" for n in _FREQUENCY_NAMES))
        if sd is not None:
            out["omega_std"] = k * _floats(table, sd, "SWEEP", path)
        return out
    t_col = table.find(*_PERIOD_NAMES)
    if t_col is not None:
        T = _floats(table, t_col, "SWEEP", path)
        import numpy as np

        bad_rows = np.flatnonzero(T <= 0)
        if bad_rows.size:
            i = int(bad_rows[0])
            raise CliError(f"SWEEP {path!r}: {t_col}[{i}]={float(T[i])!r}: a period must be > 0",
                           field=f"{t_col}[{i}]", value=float(T[i]))  # fmt: skip
        out["omega"] = 2.0 * math.pi / T
        sd = table.find(*(f"{n}_std" for n in _PERIOD_NAMES))
        if sd is not None:
            out["omega_std"] = 2.0 * math.pi * _floats(table, sd, "SWEEP", path) / T**2
    return out


# ------------------------------------------------------------------------------- commands
def _detect(args: argparse.Namespace) -> int:
    from service.analysis.detect import detect

    rec = read_record(args.file, dt=args.dt, resample=args.resample, reader=_reader_options(args))
    try:
        det = detect(rec.w, dt=rec.dt, method=args.method, kind=args.kind,
                     **_lab_options(args, rec.quantity))  # fmt: skip
    except ValueError as exc:
        err = error_from(exc, f"FILE {args.file!r}")
        if err is None:
            raise
        raise err from None
    if not (args.json or args.plot):  # the line alone: the wire models (pydantic) not loaded
        f = det.fundamental
        mode = _finite(det.modes[int(f.index)]) if f is not None else None
        emit({}, json_mode=False, text=detection_text(mode, len(det.modes),
                                                      _flag_codes([*rec.flags, *det.flags]),
                                                      rec.unit))  # fmt: skip
        return 0
    from service import convert

    doc = convert.detection(det, extra_flags=rec.flags, time_unit=rec.unit,
                            value_unit=rec.value_unit)  # fmt: skip
    if args.plot:
        from service.charts.cli import plot_detection

        plot_detection(args.plot, rec.w, rec.dt, doc, time_unit=rec.unit,
                       value_unit=rec.value_unit, title=Path(args.file).name)  # fmt: skip
    text = detection_text(doc.fundamental, len(doc.modes), [x.code for x in doc.flags], rec.unit)
    emit(doc, json_mode=args.json, text=text)
    return 0


def detection_text(fund: Any, n_modes: int, codes: list[str], unit: str | None) -> str:
    """``snapwarn detect``'s line: the fundamental (``omega``, ``sigma2``, ``sigma2_std``,
    ``regime`` as the wire's ``Fundamental`` has them), the number of modes, the flags' codes."""
    per = f" rad/{unit}" if unit else ""
    sq = f" 1/{unit}^2" if unit else ""
    return (
        f"fundamental: omega = {fund.omega}{per}, sigma2 = {fund.sigma2} +- {fund.sigma2_std}{sq} "
        f"({fund.regime})"
        if fund is not None
        else "no fundamental"
    ) + f"; {n_modes} modes; flags: {codes or 'none'}"


def _num(x: Any) -> float | None:
    """A number as the wire has it (non-finite: ``None``, see ``service.convert.plain``)."""
    v = float(x)
    return v if math.isfinite(v) else None


def _finite(mode: Any) -> argparse.Namespace:
    """A numerics mode's fields of the line as the wire has them (non-finite numbers ``None``,
    see ``service.convert.plain``)."""
    return argparse.Namespace(omega=_num(mode.omega), sigma2=_num(mode.sigma2),
                              sigma2_std=_num(mode.sigma2_std), regime=mode.regime)  # fmt: skip


def _flag_codes(items: list[Any]) -> list[str]:
    """The codes of ``service.convert.flags(items)``: each (code, message) once, in order."""
    seen: set[tuple[str, str]] = set()
    out: list[str] = []
    for f in items:
        if isinstance(f, Mapping):
            code, msg = str(f["code"]), str(f["message"])
        else:
            code, msg = f.code, f.message
        if (code, msg) not in seen:
            seen.add((code, msg))
            out.append(code)
    return out


def _predict(args: argparse.Namespace) -> int:
    from service.analysis.predict import predict

    table = _read_table(args.file, "SWEEP")
    mu_name = table.find(args.control_column or "mu")
    if mu_name is None:
        raise bad("SWEEP", args.file, f"needs a column {args.control_column or 'mu'!r} "
                  f"(columns found: {table.names}; name the control with "
                  "--control-column)")  # fmt: skip
    mu = _floats(table, mu_name, "SWEEP", args.file)
    kw: dict[str, Any] = {}
    col = {c: table.find(c) for c in ("sigma2", "sigma2_std", "omega", "omega_std",
                                      "w_static", "w_static_std")}  # fmt: skip
    # every column found goes to the numerics, as over HTTP: they use sigma2 once omega agrees
    # with it (else they name omega and the worst row), and refuse a std without its column
    alt = {} if (col["sigma2"] or col["omega"]) else _rates_from_f_or_t(table, args.file)
    if not (col["sigma2"] or col["omega"] or alt):
        raise bad("SWEEP", args.file, "needs a column 'sigma2' or 'omega' (or the "
                  "fundamental's 'frequency' [Hz] or 'period') (columns found: "
                  f"{table.names})")  # fmt: skip
    kw.update(alt)
    for name in ("sigma2", "sigma2_std", "w_static", "w_static_std"):
        if col[name]:
            kw[name] = _floats(table, col[name], "SWEEP", args.file)
    if col["omega"]:
        kw["omega"] = _rate_column(table, col["omega"], "SWEEP", args.file)
    if col["omega_std"]:
        kw["omega_std"] = _rate_column(
            table, col["omega_std"], "SWEEP", args.file, like=col["omega"]
        )
    if args.damping is not None:
        kw["damping"] = args.damping
    if args.transition:
        kw["transition"] = args.transition
    if args.a is not None:
        kw["a"] = args.a
    try:
        pred = predict(mu, **kw)
    except ValueError as exc:
        raise error_from(exc, f"SWEEP {args.file!r}") or CliError(
            f"SWEEP {args.file!r}: {exc}", field="SWEEP"
        ) from None
    if not (args.json or args.plot):  # the line alone: the wire models (pydantic) not loaded
        lo, hi = (_num(x) for x in pred.mu_star_interval)
        emit({}, json_mode=False, text=prediction_text(pred.transition, _num(pred.mu_star), lo, hi))
        return 0
    from service import convert

    doc = convert.prediction(pred)
    if args.plot:
        from service.charts.cli import plot_prediction_table

        plot_prediction_table(args.plot, mu, kw, doc, control_name=args.control_name,
                              control_unit=args.control_unit or table.units.get(mu_name),
                              time_unit=args.time_unit)  # fmt: skip
    lo, hi = doc.mu_star_interval
    emit(doc, json_mode=args.json, text=prediction_text(doc.transition, doc.mu_star, lo, hi))
    return 0


def prediction_text(transition: str, mu_star: Any, lo: Any, hi: Any) -> str:
    """``snapwarn predict``'s line: the transition, mu* and its interval (as the wire's
    ``Prediction`` has them: non-finite numbers ``None``)."""
    return f"{transition}: mu* = {mu_star} (95%: [{lo}, {hi}])"


def _progress_printer(enabled: bool, models: tuple[str, ...] = ()):
    """Truthful progress on stderr (``service.cli._progress``): kernels compiled first."""
    from service.cli._progress import make_progress, warm_kernels

    if enabled:
        warm_kernels(models)
    return make_progress(enabled)


def _warn(args: argparse.Namespace) -> int:
    from service import convert
    from service.analysis.pipeline import warn

    opts: dict[str, Any] = {}
    for name in ("end_shortening", "slenderness", "elements", "rtol"):
        if getattr(args, name, None) is not None:
            opts[name] = getattr(args, name)
    if args.max_measurements < 5:
        raise bad("--max-measurements", args.max_measurements, "must be >= 5")
    cb = _progress_printer(not args.no_progress, (args.model,))
    try:
        res = warn(args.actuation, model=args.model, damping=args.damping, snr_db=args.snr,
                   seed=args.seed, max_measurements=args.max_measurements,
                   scene_options=opts or None, progress=cb)  # fmt: skip
    finally:
        if cb is not None:
            cb.close()
    doc = convert.sweep_result(res)
    if args.plot:
        from service.charts.cli import plot_sweep

        plot_sweep(args.plot, doc, title=f"{args.actuation} ({args.model})")
    emit(doc, json_mode=args.json, text=_warn_text(doc))
    return 0


def sweep_text(
    doc: Any, name: str = "mu", unit: str | None = None, time_unit: str | None = None
) -> str:
    """The plain summary of a sweep document: the type (or why it is withheld), the transition
    point with its interval and unit (rounded to the interval), the alarm, the next safe
    control and the next record's advised length (``time_unit``: the records'); full
    precision stays in ``--json``."""
    from service.numfmt import fmt, fmt_below, fmt_interval, sig

    u = f" {unit}" if unit else ""
    p = doc.prediction
    n, aside = len(doc.measurements), getattr(doc, "n_set_aside", 0)
    used = f"{n} control(s) in the fit" + (f", {aside} record(s) set aside" if aside else "")
    half = None
    if p is None:  # why, and what the lab may still do: the alarm, the advice, the records
        why = next((f.message for f in getattr(doc, "flags", None) or ()
                    if f.code in ("too_few_records", "predictor_failed")), None)  # fmt: skip
        lines = [f"no prediction ({used})" + (f": {why}" if why else "")]
    else:
        lo, hi = p.mu_star_interval
        half = 0.5 * (hi - lo) if lo is not None and hi is not None else None
        a, b = fmt_interval(lo, hi)
        kind = p.transition
        if kind == "undetermined":
            why = next((f.message for f in p.flags if f.code == "type_withheld"), None)
            kind += f" ({why})" if why else ""
        lines = [f"type: {kind}",
                 f"{name}* = {fmt(p.mu_star, half)}{u}, 95 % interval [{a}, {b}]{u} ({used})"]
    if doc.alarm:
        al = doc.alarm[-1]
        within = f"; controls in {unit}" if unit else ""  # the reason's numbers are controls
        lines.append(f"alarm: {al.level} (rank {al.rank}{within}): {al.reason}")
    nxt = getattr(doc, "next_control", None)
    if nxt is not None and p is None:  # a step of the trust region: nothing bounds mu* yet
        lines.append(f"next {name} (not known safe: no prediction bounds {name}* yet): "
                     f"{fmt_below(nxt, half)}{u}")  # fmt: skip
    elif nxt is not None:
        lines.append(f"next safe {name}: {fmt_below(nxt, half)}{u}")
    elif p is not None:
        lines.append(f"next safe {name}: none (no safe step left)")
    else:
        lines.append(f"next safe {name}: none (no advice without a step: give --step)")
    dur, dt = getattr(doc, "record_duration", None), getattr(doc, "record_dt", None)
    if dur is not None and dt is not None:
        tu = f" {time_unit}" if time_unit else ""
        lines.append(f"next record: {sig(dur, 3)}{tu} long, sample step {sig(dt, 3)}{tu} "
                     f"({doc.record_advice})")  # fmt: skip
    for x in getattr(doc, "set_aside", None) or ():  # each by its file, with the reason
        lines.append(f"set aside: {x.reason}")
    return "\n".join(lines)


def _warn_text(doc: Any) -> str:
    """The people's summary of a sweep document (:class:`~service.schemas.SweepResult`)."""
    p = doc.prediction

    def f9(x: float | None) -> str:
        return "n/a" if x is None else f"{x:.9f}"

    from service.numfmt import fmt, fmt_interval

    if p is None:
        return f"{doc.actuation} ({doc.model}): no prediction ({doc.stopped})"
    lo, hi = p.mu_star_interval
    half = 0.5 * (hi - lo) if lo is not None and hi is not None else None
    a, b = fmt_interval(lo, hi)
    lines = [
        f"{doc.actuation} ({doc.model}): {p.transition}, a = {fmt(p.a, digits=3)}",
        f"  mu* = {fmt(p.mu_star, half)}  95%: [{a}, {b}]  "
        f"from {len(doc.measurements)} impulse responses ({doc.stopped})",
    ]
    if doc.alarm:
        lines.append(f"  alarm: {doc.alarm[-1].level} (rank {doc.alarm[-1].rank})")
    if p.baseline is not None:
        lines.append(f"  paper's rule on the same data: mu* = {fmt(p.baseline.mu_star, half)}")
    if doc.truth is not None:
        t = doc.truth
        err = "n/a" if t.error is None else f"{t.error:.2e}"
        lines.append(f"  model's own mu* = {f9(t.mu_star)}: error {err}")
    return "\n".join(lines)


_TRUE = ("1", "true", "yes", "y", "x")


def _manifest_options(
    table: Any, args: argparse.Namespace, recs: list, names: list[str], factors: Any
) -> list[dict[str, Any]]:
    """Per record the detector's options: the command line's (``--quantity``, ``--notch``,
    ``--exclude``) and the manifest's optional columns ``quantity``, ``start`` (time from the
    record's first sample, its own unit), ``notch`` (frequencies separated by spaces or ``;``)
    and ``exclude`` (1/true/yes: leave the record out, listed as set aside)."""
    cols = {k: table.find(k) for k in ("quantity", "start", "notch", "exclude")}
    unknown = set(args.exclude or ()) - set(names)
    if unknown:
        some = ", ".join(names[:5]) + ("..." if len(names) > 5 else "")
        raise bad("--exclude", sorted(unknown)[0],
                  f"names no record of the manifest (its records: {some})")  # fmt: skip
    out = []
    for k, rec in enumerate(recs):
        cell = {c: table.cells[col][k].strip() for c, col in cols.items() if col}
        q = cell.get("quantity") or args.quantity or getattr(rec, "quantity", None)
        if q and q not in ("displacement", "velocity", "acceleration"):
            raise bad("MANIFEST", args.manifest, f"quantity {q!r} of {names[k]}: expected "
                      "displacement, velocity or acceleration")  # fmt: skip
        opts: dict[str, Any] = {"quantity": q} if q else {}
        try:
            if cell.get("start"):
                opts["start"] = float(cell["start"]) * float(factors[k])
            notch = cell.get("notch")
            if notch:
                opts["notch"] = _freqs(notch.replace(";", " "))
            elif args.notch:
                opts["notch"] = args.notch
        except (ValueError, argparse.ArgumentTypeError) as exc:
            raise bad("MANIFEST", args.manifest, f"{names[k]}: {exc}") from None
        if cell.get("exclude", "").lower() in _TRUE or names[k] in (args.exclude or ()):
            opts["exclude"] = True
        out.append(opts)
    return out


def _sweep(args: argparse.Namespace) -> int:
    from service import convert
    from service.analysis.pipeline import sweep_from_signals
    from service.analysis.sweep_policy import SweepPlan, file_unreadable
    from service.recordings import RecordingError, common_time_base, manifest_columns

    table = _read_table(args.manifest, "MANIFEST")
    try:
        path_col, control_col = manifest_columns(table, args.control_column)
    except RecordingError as exc:
        raise bad("MANIFEST", args.manifest, f"{exc.why} (--control-column)") from None
    control = _floats(table, control_col, "MANIFEST", args.manifest)
    dt_col = table.find("dt")
    steps = _floats(table, dt_col, "MANIFEST", args.manifest) if dt_col else None
    paths = table.cells[path_col]
    base = Path(args.manifest).resolve().parent
    recs, names, notes, unread = [], [], {}, {}
    for k, (rel, c) in enumerate(zip(paths, control)):
        p = Path(rel)
        p = p if p.is_absolute() else base / p
        dt = args.dt if steps is None else float(steps[k])
        try:
            rec = read_record(str(p), option="MANIFEST entry", dt=dt, resample=args.resample,
                              reader=_reader_options(args))  # fmt: skip
        except CliError as exc:  # a record that cannot be read is set aside, not fatal
            unread[k] = exc
            rec = None
        recs.append((rec, float(c)))
        names.append(str(rel))
        notes[str(rel)] = rec.flags if rec is not None else ()
    if len(recs) - len(unread) < 3 and unread:
        raise next(iter(unread.values()))
    read = [k for k in range(len(recs)) if k not in unread]
    # records in different time units (one file in ms, another in s) are brought to seconds
    try:
        f_read, time_unit = common_time_base([recs[k][0].unit for k in read],
                                             [names[k] for k in read])  # fmt: skip
    except RecordingError as exc:
        err = error_from(exc, context=f"MANIFEST {args.manifest!r}")
        assert err is not None
        raise err from None
    factors = [1.0] * len(recs)
    for k, f in zip(read, f_read):
        factors[k] = f
    records = [(r.w, r.dt * f, c) if r is not None else (None, math.nan, c)
               for (r, c), f in zip(recs, factors)]  # fmt: skip
    # a start in a record's own time unit is brought to the common one with its samples
    options = _manifest_options(table, args, [r for r, _ in recs], names, factors)
    for k, exc in unread.items():  # the reader's own words, as every door gives them
        cause = exc.__context__ if isinstance(exc.__context__, RecordingError) else exc
        options[k] = {"unreadable": file_unreadable(cause)}
    cb = _progress_printer(not args.no_progress)
    try:
        plan = SweepPlan(step=args.step, margin=args.margin, band=args.band,
                         control_resolution=args.control_resolution)  # fmt: skip
        res = sweep_from_signals(records, names=names, progress=cb, plan=plan, options=options,
                                 time_unit=time_unit)  # fmt: skip
    except ValueError as exc:
        err = error_from(exc, f"MANIFEST {args.manifest!r}")
        raise err or CliError(f"MANIFEST {args.manifest!r}: {exc}", field="MANIFEST") from None
    finally:
        if cb is not None:
            cb.close()
    doc = convert.sweep_result(res, record_flags=notes, time_unit=time_unit)
    if args.plot:
        from service.charts.cli import plot_sweep

        plot_sweep(args.plot, doc, control_name=args.control_name,
                   control_unit=args.control_unit or table.units.get(control_col),
                   time_unit=time_unit)  # fmt: skip
    unit = args.control_unit or table.units.get(control_col)
    text = sweep_text(doc, args.control_name, unit, time_unit)
    emit(doc, json_mode=args.json, text=text)
    return 0


def _warn_job(actuation: str, seed: int, queue: Any) -> dict:
    """One demo sweep in a worker process; progress goes back through ``queue``."""
    from service import convert
    from service.analysis.pipeline import warn

    def cb(fraction: float, message: str) -> None:
        if queue is not None:
            queue.put((actuation, fraction, message))

    res = warn(actuation, seed=seed, max_measurements=30, progress=cb)
    return convert.sweep_result(res).model_dump(mode="json")


def _run_demo_sweeps(seed: int, show_progress: bool) -> list[dict]:
    """The three sweeps, in parallel worker processes (one per core, at most three)."""
    import multiprocessing as mp
    import os
    import queue as queue_mod
    from concurrent.futures import ProcessPoolExecutor, wait

    acts = ("asymmetric", "symmetric", "antisymmetric")
    ctx = mp.get_context("spawn")
    workers = max(1, min(len(acts), os.cpu_count() or 1))
    warm_kernels(("euler-beam",), enabled=show_progress)  # compiled once, loaded by workers
    bars = {act: Progress(f"{act:13}", position=i) for i, act in enumerate(acts)
            if show_progress}  # fmt: skip
    with ctx.Manager() as mgr:
        q = mgr.Queue() if show_progress else None
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as ex:
            futs = [ex.submit(_warn_job, act, seed + k, q) for k, act in enumerate(acts)]
            pending = set(futs)
            while pending:
                done, pending = wait(pending, timeout=0.2)
                while q is not None:
                    try:
                        act, frac, msg = q.get_nowait()
                    except queue_mod.Empty:
                        break
                    bars[act](frac, msg)
                for f in done:  # each bar ends (100 %) when its own sweep ends
                    if show_progress and f.exception() is None:
                        bars[acts[futs.index(f)]].close()
            runs = [f.result() for f in futs]
    for bar in bars.values():
        bar.close()
    return runs


def _demo(args: argparse.Namespace) -> int:
    """The main job: early warning for the three actuations of the Euler beam."""
    from service.cli.sim_cmds import beam_summary, beam_summary_text
    from service.schemas.demo import Demo

    t0 = time.perf_counter()
    summary = beam_summary()
    if not args.json:
        sys.stdout.write(beam_summary_text(summary) + "\n\n")
        sys.stdout.flush()
    runs = _run_demo_sweeps(args.seed, not args.no_progress)
    doc = Demo.model_validate(
        {"beam": summary, "warn": runs, "seconds": time.perf_counter() - t0}
    ).model_dump(mode="json")
    rows = [
        "Early warning (Euler beam, xi = 2e-4, 40 dB): true mu*, the paper's rule, ours",
        f"{'actuation':14} {'type found':24} {'true mu*':>12} {'paper rule':>12} {'ours':>14} "
        f"{'95% interval':>29} {'error':>9} {'N':>3}",
    ]

    def num(x: float | None) -> float:
        return math.nan if x is None else x

    for r in runs:
        t = r.get("truth") or {}
        p = r.get("prediction") or {}
        lo, hi = (num(v) for v in (p.get("mu_star_interval") or (None, None)))
        base = num((p.get("baseline") or {}).get("mu_star"))
        rows.append(
            f"{r['actuation']:14} {p.get('transition', 'undetermined'):24} "
            f"{num(t.get('mu_star')):12.8f} {base:12.8f} {num(p.get('mu_star')):14.10f} "
            f"[{lo:.10f}, {hi:.10f}] {num(t.get('error')):9.1e} {len(r['measurements']):3d}"
        )
    rows.append(f"({doc['seconds']:.1f} s)")
    emit(doc, json_mode=args.json, text="\n".join(rows))
    return 0


def _reader_options(args: argparse.Namespace) -> dict[str, Any]:
    """The reader's options of the command line (the API's upload fields of the same names)."""
    return {"fmt": args.format, "column": args.column, "time_column": args.time_column,
            "channel": args.channel}  # fmt: skip


def _reader_flags(p: argparse.ArgumentParser) -> None:
    """The upload's fields as options: the same reader, the same choices as over HTTP."""
    p.add_argument("--format", default=None, choices=RECORDING_FORMATS,
                   help="the file's format when its extension does not say it")  # fmt: skip
    p.add_argument("--column", default=None, metavar="NAME",
                   help="the column (CSV) or variable (NPZ, MAT) holding the signal")  # fmt: skip
    p.add_argument("--time-column", default=None, metavar="NAME",
                   help="the column or variable holding the time")  # fmt: skip
    p.add_argument("--channel", type=int, default=None, help="WAV channel (default 0)")


def _freqs(text: str) -> list[float]:
    """``--notch 50,150,250``: frequencies (comma- or space-separated)."""
    try:
        out = [float(x) for x in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected numbers like 50,150") from None
    if not out or not all(math.isfinite(f) and f > 0 for f in out):
        raise argparse.ArgumentTypeError(f"{text!r}: expected positive frequencies")
    return out


def _band(text: str) -> tuple[float, float]:
    """``--band LO,HI``: the fundamental's band of sqrt|sigma2| (rad per time unit)."""
    f = _freqs(text)
    if len(f) != 2 or not f[0] < f[1]:
        raise argparse.ArgumentTypeError(f"{text!r}: expected LO,HI with 0 < LO < HI")
    return f[0], f[1]


def _lab_options(args: argparse.Namespace, quantity: str | None = None) -> dict[str, Any]:
    """The detector's lab options from the command line: ``--quantity`` (default: the
    record's value unit says), ``--start``, ``--notch``."""
    opts = {"quantity": args.quantity or quantity,
            "start": getattr(args, "start", None), "notch": args.notch}  # fmt: skip
    return {k: v for k, v in opts.items() if v is not None}


def _lab_flags(p: argparse.ArgumentParser, *, start: bool = True) -> None:
    p.add_argument("--quantity", default=None,
                   choices=("displacement", "velocity", "acceleration"),
                   help="what the record measures (default: its value unit says: mm, mm/s, "
                   "m/s2, g; else a displacement); the static level only from a "
                   "displacement")  # fmt: skip
    if start:
        p.add_argument("--start", type=finite, default=None, metavar="T",
                       help="time (from the first sample, the record's time unit) where the "
                       "free response starts (default: the kick is located)")  # fmt: skip
    p.add_argument("--notch", type=_freqs, default=None, metavar="F[,F...]",
                   help="frequencies of stationary lines (cycles per time unit, e.g. "
                   "50,150 Hz of mains hum): fitted as lines, never the fundamental "
                   "(default: lines present before the kick or not decaying are "
                   "found)")  # fmt: skip


def _resample_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--resample", action="store_true",
                   help="interpolate non-uniform sample times onto a uniform grid (else an "
                   "error naming the worst step)")  # fmt: skip


def register(sub: argparse._SubParsersAction) -> None:
    """Add the analysis sub-commands to ``sub``."""
    p = sub.add_parser("detect", help="poles of a recorded signal")
    p.add_argument("file", help="CSV (header t,w), NPY/NPZ, WAV or .mat record")
    p.add_argument("--method", default="auto",
                   choices=("auto", "varpro", "esprit", "fft", "fft-parabolic"))  # fmt: skip
    p.add_argument("--kind", default="impulse", choices=("impulse", "ambient"))
    p.add_argument("--dt", type=finite, default=None,
                   help="sample step of a file without times (1-D .npy, one-column CSV); an "
                   "error for a file that has them")  # fmt: skip
    _resample_flag(p)
    _reader_flags(p)
    _lab_flags(p)
    add_json_flag(p)
    add_plot_flag(p, "the record, the detector's fit over it and the residual")
    p.set_defaults(func=_detect)

    p = sub.add_parser(
        "predict",
        help="mu* from a sweep table (mu, sigma2 or omega, [sigma2_std or omega_std], "
        "[w_static[, w_static_std]]); units in the header ('mu [deg]'): mu* comes in the "
        "control's unit, 'omega [Hz]' is read as 2 pi f; a table with the fundamental's "
        "'frequency' (Hz) or 'period' instead is read as omega = 2 pi f or 2 pi / T",
    )
    p.add_argument("file", metavar="SWEEP")
    p.add_argument("--control-column", default=None, metavar="NAME",
                   help="the control's column when it is not named mu")  # fmt: skip
    p.add_argument("--damping", type=float, default=None, metavar="XI",
                   help="damping xi (1/time) of the rates omega when known: twice the decay "
                   "rate of the records' envelope exp(-xi t/2) (detect's 'damping' is xi/2); "
                   "without it a damping is inferred only on decisive evidence")  # fmt: skip
    p.add_argument("--transition", default=None, choices=PREDICT_TRANSITIONS,
                   help="fit this law only (its exponent a: 1/4 saddle-node, 1/2 "
                   "pitchforks)")  # fmt: skip
    p.add_argument("--a", type=float, default=None, metavar="A",
                   help="time exponent of the law to fit, > 0 (|sigma2| ~ (mu* - mu)^(2a)): "
                   "alone, that exponent (a custom law); with --transition, that law's a or "
                   "its over-damped double (any a with 'pitchfork')")  # fmt: skip
    add_json_flag(p)
    add_plot_flag(p, "T(mu), the T^(-1/a) collapse with mu* and its interval")
    p.add_argument("--control-name", default="mu", help="the control's name on the chart")
    p.add_argument("--control-unit", default=None, help="the control's unit on the chart")
    p.add_argument("--time-unit", default=None, help="the time unit of sigma2 (chart)")
    p.set_defaults(func=_predict)

    p = sub.add_parser("warn", help="simulated early-warning sweep")
    p.add_argument("--model", default="euler-beam",
                   choices=("euler-beam", "normal-form", "cosserat", "auto"))  # fmt: skip
    p.add_argument("--actuation", required=True,
                   choices=("asymmetric", "symmetric", "antisymmetric"))  # fmt: skip
    p.add_argument("--damping", type=finite, default=2e-4)
    p.add_argument("--snr", type=finite, default=40.0)
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--max-measurements", type=int, default=30)
    p.add_argument("--end-shortening", type=finite, default=None)
    p.add_argument("--slenderness", type=finite, default=None)
    p.add_argument("--elements", type=int, default=None)
    p.add_argument("--rtol", type=finite, default=None,
                   help="simulator accuracy (resolution; backend for --model auto)")  # fmt: skip
    p.add_argument("--no-progress", action="store_true")
    add_json_flag(p)
    add_plot_flag(p, "T(mu), the T^(-1/a) collapse with mu* and its interval")
    p.set_defaults(func=_warn)

    p = sub.add_parser("sweep", help="detect recorded files then predict (header path,control"
                       "[,dt][,quantity][,start][,notch][,exclude])")  # fmt: skip
    p.add_argument("manifest", metavar="MANIFEST")
    p.add_argument("--control-column", default=None, metavar="NAME",
                   help="the manifest's control column when it is not named control")  # fmt: skip
    p.add_argument("--dt", type=finite, default=None,
                   help="sample step of the files without times (a 'dt' column "
                   "overrides)")  # fmt: skip
    _resample_flag(p)
    _reader_flags(p)
    _lab_flags(p, start=False)
    p.add_argument("--band", type=_band, default=None, metavar="LO,HI",
                   help="the fundamental's band of sqrt|sigma2| (rad per time unit): each "
                   "record's fundamental is its slowest mode inside, a record with none is "
                   "set aside (default: the mode that softens continuously across the "
                   "sweep)")  # fmt: skip
    p.add_argument("--exclude", action="append", default=None, metavar="NAME",
                   help="leave this record (its manifest path) out; listed as set aside "
                   "(repeatable; or a manifest column 'exclude')")  # fmt: skip
    p.add_argument("--no-progress", action="store_true")
    add_json_flag(p)
    add_plot_flag(p, "T(control), the T^(-1/a) collapse with the transition and its interval")
    p.add_argument("--control-name", default="control", help="the control's name on the chart")
    p.add_argument("--control-unit", default=None, help="the control's unit on the chart")
    p.add_argument("--step", type=finite, default=None,
                   help="the lab's step (default: its largest step between records)")
    p.add_argument("--margin", type=finite, default=0.0,
                   help="distance kept below the safe bound on the transition")
    p.add_argument("--control-resolution", type=finite, default=None,
                   help="finest control step the lab can set (default from the controls)")
    p.set_defaults(func=_sweep)

    p = sub.add_parser("demo", help="the main job on embedded defaults")
    p.add_argument("--seed", type=int, default=2026)
    p.add_argument("--no-progress", action="store_true")
    add_json_flag(p)
    p.set_defaults(func=_demo)
