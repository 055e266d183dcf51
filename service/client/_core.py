"""Requests as data: each SDK method builds a :class:`Call` and a parser of its response, or
a flow of them (:data:`Flow`: a generator yielding calls and :class:`Sleep` pauses).

The sync and async clients only differ in how they send a call and how they pause
(:mod:`service.client._ops`), so both share this module.
Nothing heavy is imported: numpy is used only if the caller already has it installed, and
only when a method is called.
"""

from __future__ import annotations

import importlib
import importlib.util
import io
import json
import os
import time
from collections.abc import Callable, Generator, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

from service.client.errors import JobFailed, WaitTimeout, error_for
from service.schemas import (
    Detection,
    Health,
    Job,
    JobPage,
    Prediction,
    Problem,
    SignalMeta,
    SignalPage,
    SimulationResult,
    Sweep,
)

JSON_HEADERS = {"content-type": "application/json"}
R = TypeVar("R")


@dataclass
class Call:
    method: str
    path: str
    params: dict[str, Any] | None = None
    content: bytes | None = None
    files: dict[str, Any] | None = None
    data: dict[str, Any] | None = None
    headers: dict[str, str] = field(default_factory=dict)
    parse: Callable[[Any], Any] = lambda r: r


@dataclass(frozen=True)
class Sleep:
    """A pause of a flow: ``time.sleep`` or ``asyncio.sleep`` of ``seconds``."""

    seconds: float


#: A flow: yields what to do (a :class:`Call` to send, or a :class:`Sleep`), receives the
#: parsed answer (None after a pause), returns the method's result.
Flow = Generator["Call | Sleep", Any, R]


def request_args(call: Call) -> dict[str, Any]:
    """The keyword arguments of ``httpx2.Client.request`` (or ``AsyncClient.request``)."""
    params = None if call.params is None else {k: plain(v) for k, v in call.params.items()}
    return {"method": call.method, "url": call.path, "params": params,
            "content": call.content, "files": call.files, "data": call.data,
            "headers": call.headers or None}  # fmt: skip


def has_numpy() -> bool:
    return importlib.util.find_spec("numpy") is not None


def as_list(values: Any, name: str) -> list[float] | None:
    """A list of floats from a numpy array or any sequence (NaN kept: the server judges)."""
    if values is None:
        return None
    if hasattr(values, "tolist"):
        out = values.tolist()
    else:
        out = list(values)
    if out and isinstance(out[0], (list, tuple)):
        return out  # let the server answer 422 naming the element
    return out


def plain(value: Any) -> Any:
    """A numpy scalar or 0-d array as the Python number it holds (``np.float32(0.5)`` -> 0.5,
    ``np.int64(3)`` -> 3, ``np.bool_`` -> bool), an array as nested lists; anything else as
    it is. Every value the SDK sends (JSON, form fields, query) goes through this."""
    if type(value).__module__ == "numpy":  # numpy is not imported for this
        if getattr(value, "ndim", None) == 0 and hasattr(value, "item"):
            return value.item()
        if hasattr(value, "tolist"):
            return value.tolist()
    return value


def _json_default(value: Any) -> Any:
    out = plain(value)
    if out is value:
        raise TypeError(f"Object of type {type(value).__name__} is not JSON serializable")
    return out


def dumps(doc: Any) -> bytes:
    """JSON with NaN/inf written as literals, so the server can name them in its 422; numpy
    scalars and arrays anywhere in ``doc`` are written as numbers and lists (:func:`plain`)."""
    return json.dumps(doc, allow_nan=True, separators=(",", ":"), default=_json_default).encode()


def form_text(value: Any) -> str:
    """A multipart form field's text: numbers as Python writes them (numpy scalars too, see
    :func:`plain`), booleans as ``true``/``false``, mappings and lists as JSON."""
    v = plain(value)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(float(v))
    if isinstance(v, (Mapping, list, tuple)):
        return dumps(v).decode()
    return str(v)


def form_fields(fields: Mapping[str, Any]) -> dict[str, str]:
    """The multipart form fields of ``fields`` that are not None (:func:`form_text`)."""
    return {k: form_text(v) for k, v in fields.items() if v is not None}


def raise_for_problem(response: Any) -> None:
    if response.status_code < 400:
        return
    try:
        doc = response.json()
        problem = Problem.model_validate(doc)
    except Exception:  # noqa: BLE001 - not a problem document (a proxy, a crash)
        problem = Problem(
            title=response.reason_phrase or "Error",
            status=response.status_code,
            detail=response.text[:500] or None,
        )
    raise error_for(problem, method=response.request.method, url=str(response.request.url))


def _model(cls: Any) -> Callable[[Any], Any]:
    return lambda r: cls.model_validate(r.json())


def _to_arrays(t: Any, w: Any, as_numpy: bool | None) -> tuple[Any, Any]:
    use = has_numpy() if as_numpy is None else as_numpy
    if use:
        np = importlib.import_module("numpy")
        return np.asarray(t, dtype=np.float64), np.asarray(w, dtype=np.float64)
    return list(t), list(w)


def _npy_or_json(as_numpy: bool | None) -> tuple[dict[str, str], Callable[[Any], Any]]:
    use = has_numpy() if as_numpy is None else as_numpy
    if use:

        def parse_npy(r: Any) -> tuple[Any, Any]:
            np = importlib.import_module("numpy")
            a = np.load(io.BytesIO(r.content), allow_pickle=False)
            return a[:, 0].copy(), a[:, 1].copy()

        return {"format": "npy"}, parse_npy

    def parse_json(r: Any) -> tuple[Any, Any]:
        d = r.json()
        return d["t"], d["w"]

    return {"format": "json"}, parse_json


# --- calls -----------------------------------------------------------------------------------
def health() -> Call:
    return Call("GET", "/healthz", parse=_model(Health))


def upload_signal(
    w: Any,
    *,
    t: Any = None,
    dt: float | None = None,
    t0: float | None = None,
    unit: str | None = None,
    value_unit: str | None = None,
    control: Mapping[str, Any] | None = None,
    metadata: Mapping[str, Any] | None = None,
    name: str | None = None,
    resample: bool = False,
) -> Call:
    doc: dict[str, Any] = {"w": as_list(w, "w")}
    if resample:
        doc["resample"] = True
    for k, v in (
        ("t", as_list(t, "t")),
        ("dt", dt),
        ("t0", t0),
        ("unit", unit),
        ("value_unit", value_unit),
        ("name", name),
    ):
        if v is not None:
            doc[k] = v
    if control is not None:
        doc["control"] = dict(control)
    if metadata is not None:
        doc["metadata"] = dict(metadata)
    return Call(
        "POST",
        "/v1/signals",
        content=dumps(doc),
        headers=dict(JSON_HEADERS),
        parse=_model(SignalMeta),
    )


def upload_file(
    file: str | os.PathLike | bytes,
    *,
    filename: str | None = None,
    format: str | None = None,
    **fields: Any,
) -> Call:
    if isinstance(file, (bytes, bytearray)):
        data = bytes(file)
        fname = filename or f"signal.{format or 'csv'}"
    else:
        with open(file, "rb") as fh:
            data = fh.read()
        fname = filename or os.path.basename(os.fspath(file))
    form = form_fields({"format": format, **fields})
    return Call(
        "POST", "/v1/signals", files={"file": (fname, data)}, data=form, parse=_model(SignalMeta)
    )


def list_signals(*, limit: int = 50, offset: int = 0) -> Call:
    return Call(
        "GET", "/v1/signals", params={"limit": limit, "offset": offset}, parse=_model(SignalPage)
    )


def list_jobs(
    *, status: str | None = None, kind: str | None = None, limit: int = 50, offset: int = 0
) -> Call:
    params: dict[str, Any] = {"limit": limit, "offset": offset}
    if status:
        params["status"] = status
    if kind:
        params["kind"] = kind
    return Call("GET", "/v1/jobs", params=params, parse=_model(JobPage))


def get_signal(signal_id: str) -> Call:
    return Call("GET", f"/v1/signals/{signal_id}", parse=_model(SignalMeta))


def signal_data(signal_id: str, *, as_numpy: bool | None = None) -> Call:
    params, parse = _npy_or_json(as_numpy)
    return Call("GET", f"/v1/signals/{signal_id}/data", params=params, parse=parse)


def download_signal(signal_id: str, *, format: str = "csv") -> Call:
    return Call(
        "GET", f"/v1/signals/{signal_id}/data", params={"format": format}, parse=lambda r: r.content
    )


def delete_signal(signal_id: str) -> Call:
    return Call("DELETE", f"/v1/signals/{signal_id}", parse=lambda r: None)


def signal_plot(signal_id: str) -> Call:
    return Call("GET", f"/v1/signals/{signal_id}/plot.png", parse=lambda r: r.content)


def simulate(**scene: Any) -> Call:
    doc = {k: v for k, v in scene.items() if v is not None}
    return Call(
        "POST",
        "/v1/simulations",
        content=dumps(doc),
        headers=dict(JSON_HEADERS),
        parse=_model(SimulationResult),
    )


def snap(**request: Any) -> Call:
    from service.schemas.snaps import SnapAnswer

    doc = {k: v for k, v in request.items() if v is not None}
    return Call("POST", "/v1/snaps", content=dumps(doc), headers=dict(JSON_HEADERS),
                parse=_model(SnapAnswer))  # fmt: skip


def detect(
    signal_id: str | None = None,
    *,
    w: Any = None,
    t: Any = None,
    dt: float | None = None,
    method: str = "auto",
    quantity: str | None = None,
    start: float | None = None,
    notch: Any = None,
) -> Call:
    doc: dict[str, Any] = {"method": method}
    if signal_id is not None:
        doc["signal_id"] = signal_id
    lab = (("quantity", quantity), ("start", start),
           ("notch", _column_or_list(notch, "notch")))  # fmt: skip
    for k, v in (("w", as_list(w, "w")), ("t", as_list(t, "t")), ("dt", dt), *lab):
        if v is not None:
            doc[k] = v
    return Call(
        "POST",
        "/v1/detections",
        content=dumps(doc),
        headers=dict(JSON_HEADERS),
        parse=_model(Detection),
    )


def _column_or_list(values: Any, name: str) -> list[float] | None:
    """A column as a list; a single number as a list of one (``notch=50``)."""
    if isinstance(values, (int, float)) or getattr(values, "ndim", None) == 0:
        return [float(values)]
    return as_list(values, name)


def _column_or_number(values: Any, name: str) -> Any:
    """A column as a list, or a single number as it is (``w_static_std=1e-3``)."""
    if isinstance(values, (int, float)) or getattr(values, "ndim", None) == 0:
        return float(values)
    return as_list(values, name)


def predict(
    mu: Any,
    sigma2: Any = None,
    *,
    sigma2_std: Any = None,
    omega: Any = None,
    omega_std: Any = None,
    omega_unit: str | None = None,
    w_static: Any = None,
    w_static_std: Any = None,
    damping: float | None = None,
    transition: str | None = None,
    a: float | None = None,
    level: float | None = None,
) -> Call:
    """The ``POST /v1/predictions`` call of :meth:`Client.predict` (columns as lists, the
    options present only when given)."""
    doc: dict[str, Any] = {"mu": as_list(mu, "mu")}
    for k, v in (
        ("sigma2", as_list(sigma2, "sigma2")),
        ("sigma2_std", as_list(sigma2_std, "sigma2_std")),
        ("omega", as_list(omega, "omega")),
        ("omega_std", as_list(omega_std, "omega_std")),
        ("omega_unit", omega_unit),
        ("w_static", as_list(w_static, "w_static")),
        ("w_static_std", None if w_static_std is None else _column_or_number(w_static_std,
                                                                            "w_static_std")),
        ("damping", damping),
        ("transition", transition),
        ("a", a),
        ("level", level),
    ):  # fmt: skip
        if v is not None:
            doc[k] = v
    return Call(
        "POST",
        "/v1/predictions",
        content=dumps(doc),
        headers=dict(JSON_HEADERS),
        parse=_model(Prediction),
    )


def _measurement(m: Any) -> dict[str, Any]:
    if isinstance(m, str):
        return {"signal_id": m}
    if isinstance(m, Mapping):
        return dict(m)
    if hasattr(m, "id") and not isinstance(m, Sequence):  # a SignalMeta
        return {"signal_id": m.id}
    sid, value = m
    sid = getattr(sid, "id", sid)
    return {"signal_id": sid, "control_value": value}


def create_sweep(
    measurements: Iterable[Any] | None = None,
    *,
    simulate: Mapping[str, Any] | None = None,
    name: str | None = None,
    control: str | None = None,
    unit: str | None = None,
    band: tuple[float, float] | None = None,
    notch: Any = None,
    exclude: Iterable[str] = (),
) -> Call:
    doc: dict[str, Any] = {}
    if measurements is not None:
        doc["measurements"] = [_measurement(m) for m in measurements]
        out = set(exclude)
        for m in doc["measurements"]:
            if m["signal_id"] in out:
                m["exclude"] = True
    if band is not None:
        doc["band"] = [float(band[0]), float(band[1])]
    if notch is not None:
        doc["notch"] = _column_or_list(notch, "notch")
    if simulate is not None:
        doc["simulate"] = {k: v for k, v in simulate.items() if v is not None}
    if name is not None:
        doc["name"] = name
    named = {k: v for k, v in (("name", control), ("unit", unit)) if v is not None}
    if named:
        doc["control"] = named
    return Call(
        "POST", "/v1/sweeps", content=dumps(doc), headers=dict(JSON_HEADERS), parse=_model(Sweep)
    )


def get_sweep(sweep_id: str) -> Call:
    return Call("GET", f"/v1/sweeps/{sweep_id}", parse=_model(Sweep))


def sweep_plot(sweep_id: str, *, format: str = "png") -> Call:
    if format not in ("png", "svg"):
        raise ValueError(f"format must be 'png' or 'svg', got {format!r}")
    return Call("GET", f"/v1/sweeps/{sweep_id}/plot.{format}", parse=lambda r: r.content)


def get_job(job_id: str) -> Call:
    return Call("GET", f"/v1/jobs/{job_id}", parse=_model(Job))


def job_id_of(obj: Any) -> str:
    """The job id behind a Job, Sweep, SimulationResult or an id string."""
    if isinstance(obj, str):
        return obj
    if isinstance(obj, Job):
        return obj.id
    if isinstance(obj, Sweep):
        return obj.job.id
    if isinstance(obj, SimulationResult):
        if obj.job is None:
            raise ValueError("this simulation ran at once; there is no job to wait for")
        return obj.job.id
    raise TypeError(f"cannot wait for {type(obj).__name__}")


class Bar:
    """A tqdm progress bar on stderr (or nothing), fed with job progress."""

    def __init__(self, enabled: bool, desc: str) -> None:
        self._bar = None
        if enabled:
            from tqdm import tqdm

            self._bar = tqdm(
                total=1000,
                desc=desc,
                unit="‰",
                leave=True,
                bar_format="{desc}: {percentage:3.0f}%|{bar}| {postfix}",
            )
        self._n = 0

    def update(self, job: Job) -> None:
        if self._bar is None:
            return
        n = int(round(job.progress.fraction * 1000))
        if n > self._n:
            self._bar.update(n - self._n)
            self._n = n
        self._bar.set_postfix_str(f"{job.status}: {job.progress.message}"[:60], refresh=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def wait_flow(
    job: Any, *, progress: bool, timeout: float | None, poll: float, raise_on_failure: bool
) -> Flow[Any]:
    """Poll a job until it ends (the clients' ``wait``)."""
    jid = job_id_of(job)
    poll = float(poll)  # time.sleep refuses numpy scalars
    timeout = None if timeout is None else float(timeout)
    bar = Bar(progress, f"job {jid[:8]}")
    deadline = None if timeout is None else time.monotonic() + timeout
    try:
        while True:
            j = yield get_job(jid)
            bar.update(j)
            if j.done:
                break
            if deadline is not None and time.monotonic() > deadline:
                raise WaitTimeout(f"job {jid} still {j.status} after {timeout} s")
            yield Sleep(poll)
    finally:
        bar.close()
    if j.status == "failed" and raise_on_failure:
        raise JobFailed(j)
    return (yield get_sweep(job.id)) if isinstance(job, Sweep) else j
