"""The kinds of atlas cells: their parameters (validated) and the function that computes one.

- ``bifurcation``: mu* and the transition of a backend of ``sim.backends`` (``normal-form``,
  ``euler-beam``, or the ``cosserat`` rectangular strip at its end-shortening dL/L,
  slenderness h/L, Poisson ratio, and elements or requested accuracy ``rtol``), with the
  estimated discretisation error of mu*: the paper's Table 1.
- ``warn``: one simulated early-warning sweep (``service.analysis.pipeline.warn``): the
  prediction's error against the model's own mu*, whether the 95 % interval covers it, the
  impulse responses used, and the paper's two-point rule on the same measurements.
- ``sweep``: one lab campaign given as a manifest (CSV ``path,control``) analysed by
  ``sweep_from_signals``; with ``mu_star_true`` (the snap the lab saw) also error and coverage.

A cell never raises for a bad scene or a failed analysis: it returns a failed
:class:`CellResult` whose ``error`` names the parameter and the value (errors are data; they
are deterministic, so they are persisted and not retried). Only a lost worker makes the engine
run a cell again.
"""

from __future__ import annotations

import math
import os
import socket
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

ACTUATIONS = ("asymmetric", "symmetric", "antisymmetric")
WARN_MODELS = ("normal-form", "euler-beam", "cosserat", "auto")
BIFURCATION_MODELS = ("normal-form", "euler-beam", "cosserat")
DETECT_METHODS = ("auto", "varpro", "esprit", "fft", "fft-parabolic")


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of a kind: its type, domain and default.

    ``kind`` is "float", "int", "choice" or "str"; ``lo``/``hi`` bound numbers (``open_lo``
    makes the lower bound strict); ``nullable`` admits ``null`` (e.g. no noise).
    """

    kind: str
    default: Any = None
    required: bool = False
    choices: tuple[Any, ...] = ()
    lo: float | None = None
    hi: float | None = None
    open_lo: bool = False
    nullable: bool = False
    help: str = ""

    def check(self, value: Any) -> Any:
        """The value, normalised (ints as int, floats as float); ValueError naming the domain."""
        if value is None:
            if self.nullable:
                return None
            raise ValueError("must not be null")
        if self.kind == "choice":
            if value not in self.choices:
                raise ValueError(f"must be one of {list(self.choices)}, got {value!r}")
            return value
        if self.kind == "str":
            if not isinstance(value, str) or not value or len(value) > 4096:
                raise ValueError(f"must be a non-empty string, got {value!r}")
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"must be a number, got {value!r}")
        if self.kind == "int":
            if int(value) != value:
                raise ValueError(f"must be an integer, got {value!r}")
            value = int(value)
        else:
            value = float(value)
            if not math.isfinite(value):
                raise ValueError(f"must be finite, got {value!r}")
        if self.lo is not None and (value <= self.lo if self.open_lo else value < self.lo):
            raise ValueError(f"must be {'>' if self.open_lo else '>='} {self.lo:g}, got {value!r}")
        if self.hi is not None and value > self.hi:
            raise ValueError(f"must be <= {self.hi:g}, got {value!r}")
        return value


@dataclass(frozen=True)
class CellResult:
    """The outcome of one cell (what is persisted, one row per cell).

    Attributes
    ----------
    key : str
        The cell's stable hash (see :func:`service.atlas.spec.cell_key`).
    index : int
        Position of the cell in its spec.
    inputs : dict
        The cell's complete inputs.
    status : {"ok", "failed"}
    results : dict
        Flat scalar results of the kind (JSON values; non-finite numbers as None).
    flags : tuple of dict
        ``{"code", "message"}`` reasons to doubt the results.
    error : dict or None
        For a failed cell: ``type``, ``parameter``, ``value``, ``message``.
    seconds : float
        Wall time of the computation in the worker (s).
    cpu_seconds : float
        CPU time of the worker process during the computation (s).
    worker : str
        Which worker computed it (dask address, or host:pid when run serially).
    """

    key: str
    index: int
    inputs: dict[str, Any]
    status: str
    results: dict[str, Any] = field(default_factory=dict)
    flags: tuple[dict[str, str], ...] = ()
    error: dict[str, Any] | None = None
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    worker: str = ""

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CellResult:
        return cls(key=d["key"], index=int(d["index"]), inputs=dict(d["inputs"]),
                   status=d["status"], results=dict(d.get("results") or {}),
                   flags=tuple(dict(f) for f in d.get("flags") or ()), error=d.get("error"),
                   seconds=float(d.get("seconds") or 0.0),
                   cpu_seconds=float(d.get("cpu_seconds") or 0.0),
                   worker=str(d.get("worker") or ""))  # fmt: skip


Runner = Callable[[dict[str, Any]], tuple[dict[str, Any], list[dict[str, str]]]]


@dataclass(frozen=True)
class KindSpec:
    """A kind of cell: its parameters, a cross-field check and the computation."""

    name: str
    params: dict[str, ParamSpec]
    run: Runner
    cross_check: Callable[[dict[str, Any]], None] = lambda inputs: None
    metrics: tuple[str, ...] = ()
    doc: str = ""


def _num(v: Any) -> Any:
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return v
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(f):
        return None
    return int(v) if isinstance(v, int) else f


# --------------------------------------------------------------------------- bifurcation
def _rod_params() -> dict[str, ParamSpec]:
    return {
        "end_shortening": ParamSpec("float", 1e-2, lo=0.0, hi=0.49, open_lo=True,
                                    help="dL/L (Cosserat rod)"),
        "slenderness": ParamSpec("float", 1e-3, lo=0.0, hi=0.49, open_lo=True,
                                 help="h/L of the rectangular strip (Cosserat rod)"),
        "poisson": ParamSpec("float", 0.5, lo=0.0, hi=0.5,
                             help="Poisson ratio (shear modulus, Cowper shear coefficient)"),
        "elements": ParamSpec("int", None, lo=4, hi=4000, nullable=True,
                              help="elements of the rod (even); null: chosen from rtol"),
        "rtol": ParamSpec("float", 2e-4, lo=1e-8, hi=0.1, open_lo=True,
                          help="requested relative accuracy of mu* (picks the elements)"),
    }  # fmt: skip


BIFURCATION_PARAMS = {
    "actuation": ParamSpec("choice", required=True, choices=ACTUATIONS),
    "model": ParamSpec("choice", "cosserat", choices=BIFURCATION_MODELS),
    **_rod_params(),
}


def _rod_check(inp: dict[str, Any]) -> None:
    from service.analysis.errors import ParameterError

    n = inp.get("elements")
    if inp["model"] in ("cosserat", "auto") and n is not None and n % 2:
        raise ParameterError("elements", n,
                             f"elements must be even for the Cosserat rod, got {n}")


def _scene(inp: dict[str, Any], **extra: Any) -> Any:
    from sim.scene import Scene

    rod = {k: inp[k] for k in ("end_shortening", "slenderness", "poisson", "elements", "rtol")}
    return Scene(actuation=inp["actuation"], **rod, **extra)


def _run_bifurcation(inp: dict[str, Any]) -> tuple[dict[str, Any], list[dict[str, str]]]:
    """mu* of the backend's own model at its resolution (``sim.backends``)."""
    from sim.backends import BACKENDS

    b = BACKENDS[inp["model"]].bifurcation(_scene(inp))
    flags: list[dict[str, str]] = []
    if "note" in b.info:
        flags.append({"code": "transition_changed", "message": str(b.info["note"])})
    err = b.mu_star_error
    if err is not None and inp["model"] == "cosserat" and err > inp["rtol"] * abs(b.mu_star):
        flags.append({"code": "coarse", "message": f"estimated discretisation error of mu* "
                      f"{err:.2e} with elements={b.elements} exceeds rtol x mu* = "
                      f"{inp['rtol'] * abs(b.mu_star):.2e}"})
    res = {
        "mu_star": _num(b.mu_star),
        "lambda_star": _num(b.lambda_star),
        "transition": b.transition,
        "secondary_mu_star": _num(b.secondary[0].mu_star) if b.secondary else None,
        "mu_star_error": _num(err),
        "elements": b.elements,
        "newton_solves": _num(b.info.get("newton_solves")),
    }
    return res, flags


# --------------------------------------------------------------------------- warn
WARN_PARAMS = {
    "actuation": ParamSpec("choice", required=True, choices=ACTUATIONS),
    "model": ParamSpec("choice", "euler-beam", choices=WARN_MODELS),
    "damping": ParamSpec("float", 2e-4, lo=0.0, hi=10.0, help="xi"),
    "snr_db": ParamSpec("float", 40.0, lo=-20.0, hi=300.0, nullable=True,
                        help="noise of every record (dB), null for none"),
    "seed": ParamSpec("int", 0, lo=0, hi=2**31 - 1, nullable=True),
    "max_measurements": ParamSpec("int", 30, lo=5, hi=200),
    "kick": ParamSpec("float", 1e-2, lo=0.0, hi=1.0, open_lo=True),
    **_rod_params(),
}


def _run_warn(inp: dict[str, Any]) -> tuple[dict[str, Any], list[dict[str, str]]]:
    from service import convert
    from service.analysis.pipeline import warn

    opts = None
    if inp["model"] in ("cosserat", "auto"):
        opts = {k: inp[k] for k in ("end_shortening", "slenderness", "poisson", "elements",
                                    "rtol")}
    res = warn(inp["actuation"], model=inp["model"], damping=inp["damping"],
               snr_db=inp["snr_db"], seed=inp["seed"], max_measurements=inp["max_measurements"],
               kick=inp["kick"], scene_options=opts)  # fmt: skip
    doc, flags = _sweep_outline(res)
    doc.setdefault("transition", "undetermined")
    truth = convert.plain(res.truth) or {}
    return _prediction_results(doc, truth), flags


def _sweep_outline(res: Any) -> tuple[dict[str, Any], list[dict[str, str]]]:
    """What a cell keeps of a sweep (``WarnResult``), read from its wire document, and the
    sweep's and the prediction's flags in order."""
    from service import convert

    sweep = convert.sweep_result(res)
    p = sweep.prediction
    doc: dict[str, Any] = {"n_measurements": len(sweep.measurements), "stopped": sweep.stopped}
    if p is not None:
        doc.update(mu_star=p.mu_star, mu_star_interval=p.mu_star_interval, a=p.a,
                   transition=p.transition,
                   baseline=p.baseline.model_dump() if p.baseline is not None else None)
    pflags = res.prediction.flags if res.prediction is not None else ()
    return doc, [convert.flag(f).model_dump() for f in (*res.flags, *pflags)]


def _prediction_results(doc: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any]:
    lo, hi = doc.get("mu_star_interval") or (None, None)
    base = (doc.get("baseline") or {}).get("mu_star")
    true = truth.get("mu_star")
    mu = doc.get("mu_star")
    err = mu - true if mu is not None and true is not None else None
    base_err = base - true if base is not None and true is not None else None
    out = {
        "mu_star": _num(mu), "mu_star_lo": _num(lo), "mu_star_hi": _num(hi),
        "transition": doc.get("transition"), "a": _num(doc.get("a")),
        "responses": _num(doc.get("n_measurements")), "stopped": doc.get("stopped"),
        "mu_star_true": _num(true), "transition_true": truth.get("transition"),
        "error": _num(err), "abs_error": _num(abs(err)) if err is not None else None,
        "covered": (bool(lo <= true <= hi) if None not in (lo, hi, true) else None),
        "transition_correct": (doc.get("transition") == truth["transition"]
                               if truth.get("transition") else None),
        "paper_mu_star": _num(base), "paper_error": _num(base_err),
        "better_than_paper": (abs(err) <= abs(base_err)
                              if err is not None and base_err is not None else None),
    }  # fmt: skip
    return out


# --------------------------------------------------------------------------- sweep
SWEEP_PARAMS = {
    "manifest": ParamSpec("str", required=True,
                          help="CSV with the header path,control (paths relative to it)"),
    "method": ParamSpec("choice", "auto", choices=DETECT_METHODS),
    "mu_star_true": ParamSpec("float", None, nullable=True,
                              help="the control value where the strip was seen to snap"),
    "transition_true": ParamSpec("choice", None, nullable=True,
                                 choices=("saddle-node", "subcritical-pitchfork",
                                          "supercritical-pitchfork")),
}


def _read_manifest(path: str) -> tuple[list[tuple[Any, float, float]], list[str]]:
    """The records of a manifest (``path,control``), read as ``snapwarn sweep`` reads it:
    the same table rules (:func:`service.recordings.read_table`), the same columns
    (:func:`service.recordings.manifest_columns`) and the records brought to one time unit
    (:func:`service.recordings.common_time_base`)."""
    from pathlib import Path

    from service.analysis.errors import ParameterError
    from service.recordings import (
        RecordingError,
        common_time_base,
        manifest_columns,
        read_table,
    )

    p = Path(path)
    if not p.is_file():
        raise ParameterError("manifest", path, f"manifest {path!r} is not a readable file")
    try:
        table = read_table(p.read_bytes(), what="file")
        path_col, control_col = manifest_columns(table)
        control = table.floats(control_col, what="file")
    except RecordingError as exc:
        raise ParameterError("manifest", path, f"manifest {path!r}: {exc}") from None
    recs, names = [], []
    for rel, c in zip(table.cells[path_col], control, strict=True):
        q = Path(rel)
        recs.append((_read_record(q if q.is_absolute() else p.resolve().parent / q), float(c)))
        names.append(rel)
    try:
        factors, _ = common_time_base([r.unit for r, _ in recs], names)
    except RecordingError as exc:
        raise ParameterError("manifest", path, f"manifest {path!r}: {exc}") from None
    return [(r.w, r.dt * f, c) for (r, c), f in zip(recs, factors, strict=True)], names


def _read_record(path: Any) -> Any:
    """One lab file through the service's one reader (``service.recordings``)."""
    from service.analysis.errors import ParameterError
    from service.recordings import RecordingError, read_file

    try:
        return read_file(path)
    except RecordingError as exc:
        raise ParameterError("manifest", str(path), f"record {str(path)!r}: {exc}") from None


def _run_sweep(inp: dict[str, Any]) -> tuple[dict[str, Any], list[dict[str, str]]]:
    from service.analysis.pipeline import sweep_from_signals

    records, names = _read_manifest(inp["manifest"])
    res = sweep_from_signals(records, names=names, method=inp["method"])
    doc, flags = _sweep_outline(res)
    truth = {"mu_star": inp["mu_star_true"], "transition": inp["transition_true"]}
    return _prediction_results(doc, truth), flags


KINDS: dict[str, KindSpec] = {
    "bifurcation": KindSpec("bifurcation", BIFURCATION_PARAMS, _run_bifurcation,
                            _rod_check, ("mu_star", "type"),
                            "mu* and the transition of a backend"),
    "warn": KindSpec("warn", WARN_PARAMS, _run_warn, _rod_check, metrics=(
        "error", "coverage", "responses", "type", "paper_error"),
        doc="a simulated early-warning sweep against the model's mu* and the paper's rule"),
    "sweep": KindSpec("sweep", SWEEP_PARAMS, _run_sweep,
                      metrics=("mu_star", "type", "responses", "error", "coverage"),
                      doc="a recorded campaign (manifest) analysed"),
}  # fmt: skip


def worker_name() -> str:
    """The dask worker's address, or ``host:pid`` outside a dask worker."""
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def run_cell(kind: str, key: str, index: int, inputs: dict[str, Any]) -> CellResult:
    """Compute one cell (in a worker). Errors of the numerics come back as a failed result.

    Parameters
    ----------
    kind : str
        A key of :data:`KINDS`.
    key, index : str, int
        The cell's stable hash and its position in the spec (carried into the result).
    inputs : dict
        The cell's complete, validated inputs.
    """
    spec = KINDS[kind]
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        results, flags = spec.run(dict(inputs))
        status, error = "ok", None
    except Exception as exc:  # noqa: BLE001 - every failure of a cell is recorded as data
        results, flags, status = {}, [], "failed"
        error = {
            "type": type(exc).__name__, "parameter": getattr(exc, "parameter", None),
            "value": _num(getattr(exc, "value", None)), "message": str(exc)[:2000],
        }  # fmt: skip
    return CellResult(
        key=key, index=index, inputs=dict(inputs), status=status, results=results,
        flags=tuple({"code": str(f.get("code")), "message": str(f.get("message"))}
                    for f in flags),
        error=error, seconds=time.perf_counter() - t0, cpu_seconds=time.process_time() - c0,
        worker=worker_name(),
    )  # fmt: skip
