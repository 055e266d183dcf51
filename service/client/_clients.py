"""``Client`` (blocking) and ``AsyncClient`` (asyncio) over httpx2.

Every method is declared once, in :class:`Api`, as a flow of requests described by
:mod:`service.client._core` (:mod:`service.client._ops`); the two clients only differ in their
transport: ``_run`` sends one request (blocking, or awaited) and the flow's pauses sleep
(``time.sleep``, ``asyncio.sleep``).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from typing import Any, ClassVar, Literal

import httpx2

from service.client import _core as core
from service.client import live
from service.client._core import Flow
from service.client._ops import operation
from service.client.atlases import AtlasOperations
from service.client.errors import TransportFailed
from service.client.live import AsyncLiveSweep, LiveSweep
from service.schemas import (
    Detection,
    Health,
    Job,
    JobPage,
    Prediction,
    SignalMeta,
    SignalPage,
    SimulationResult,
    Sweep,
)


def _headers(api_key: str | None, extra: dict[str, str] | None) -> dict[str, str]:
    h = {"user-agent": "snapwarn-sdk/0.1", "accept": "application/json"}
    if api_key:
        h["authorization"] = f"Bearer {api_key}"
    h.update(extra or {})
    return h


class Api(AtlasOperations):
    """The SDK's methods, declared once for :class:`Client` and :class:`AsyncClient`."""

    @operation
    def health(self) -> Flow[Health]:
        """``GET /healthz``."""
        return (yield core.health())

    @operation
    def upload_signal(
        self,
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
    ) -> Flow[SignalMeta]:
        """``POST /v1/signals`` (JSON): samples ``w`` with their times ``t`` or step ``dt``.

        ``control`` is ``{"name", "value", "unit"}``; ``resample`` interpolates non-uniform
        times onto a uniform grid (else the server answers 422 naming the worst step).
        """
        return (yield core.upload_signal(
            w, t=t, dt=dt, t0=t0, unit=unit, value_unit=value_unit, control=control,
            metadata=metadata, name=name, resample=resample,
        ))  # fmt: skip

    @operation
    def upload_file(
        self,
        file: str | os.PathLike[str] | bytes,
        *,
        filename: str | None = None,
        format: str | None = None,
        dt: float | None = None,
        t0: float | None = None,
        column: str | None = None,
        time_column: str | None = None,
        channel: int | None = None,
        resample: bool | None = None,
        unit: str | None = None,
        value_unit: str | None = None,
        control_name: str | None = None,
        control_value: float | None = None,
        control_unit: str | None = None,
        metadata: Mapping[str, Any] | None = None,
        name: str | None = None,
    ) -> Flow[SignalMeta]:
        """``POST /v1/signals`` (multipart): a path or bytes (CSV, NPY, NPZ, WAV, MAT).

        ``dt`` gives the step of a file without times (1-D .npy, one-column CSV); the server
        refuses it for a file that has times. See ``service.recordings`` for the layouts.
        """
        return (yield core.upload_file(
            file, filename=filename, format=format, dt=dt, t0=t0, column=column,
            time_column=time_column, channel=channel, resample=resample, unit=unit,
            value_unit=value_unit, control_name=control_name, control_value=control_value,
            control_unit=control_unit, metadata=metadata, name=name,
        ))  # fmt: skip

    @operation
    def list_signals(self, *, limit: int = 50, offset: int = 0) -> Flow[SignalPage]:
        """``GET /v1/signals``: a page of signals, newest first."""
        return (yield core.list_signals(limit=limit, offset=offset))

    @operation
    def list_jobs(
        self,
        *,
        status: str | None = None,
        kind: str | None = None,
        limit: int = 50,
        offset: int = 0,
    ) -> Flow[JobPage]:
        """``GET /v1/jobs``: a page of jobs, newest first (filtered by status and kind)."""
        return (yield core.list_jobs(status=status, kind=kind, limit=limit, offset=offset))

    @operation
    def get_signal(self, signal_id: str) -> Flow[SignalMeta]:
        """``GET /v1/signals/{id}``; a simulated signal's ``.simulation`` is its typed
        metadata (``.simulation.info.resolution``, ``.error``, ``.auto``...)."""
        return (yield core.get_signal(signal_id))

    @operation
    def signal_data(self, signal_id: str, *, as_numpy: bool | None = None) -> Flow[tuple[Any, Any]]:
        """``(t, w)`` exactly as stored: numpy arrays where numpy is installed, else lists."""
        return (yield core.signal_data(signal_id, as_numpy=as_numpy))

    @operation
    def download_signal(self, signal_id: str, *, format: str = "csv") -> Flow[bytes]:
        """The stored samples as a CSV, NPY or JSON file's bytes."""
        return (yield core.download_signal(signal_id, format=format))

    @operation
    def delete_signal(self, signal_id: str) -> Flow[None]:
        """``DELETE /v1/signals/{id}``."""
        return (yield core.delete_signal(signal_id))

    @operation
    def signal_plot(self, signal_id: str) -> Flow[bytes]:
        """PNG chart of a signal."""
        return (yield core.signal_plot(signal_id))

    @operation
    def simulate(self, **scene: Any) -> Flow[SimulationResult]:
        """``POST /v1/simulations``: ``.signal`` at once (``.signal.simulation``: the scene,
        the backend and its typed report), or ``.job`` to :meth:`wait` for."""
        return (yield core.simulate(**scene))

    @operation
    def snap(self, **request: Any) -> Flow[Any]:
        """``POST /v1/snaps``: ``.snap`` at once (normal form), or ``.job`` to :meth:`wait` for
        (its result is the snap document)."""
        return (yield core.snap(**request))

    @operation
    def detect(
        self,
        signal_id: str | None = None,
        *,
        w: Any = None,
        t: Any = None,
        dt: float | None = None,
        method: str = "auto",
        quantity: str | None = None,
        start: float | None = None,
        notch: Any = None,
    ) -> Flow[Detection]:
        """``POST /v1/detections``: a stored signal's id, or ``w`` with ``t`` or ``dt``.

        ``quantity`` ("displacement", "velocity", "acceleration"; default: the stored
        signal's unit says, else a displacement), ``start`` (time where the free response
        starts; default: located) and ``notch`` (frequencies of stationary lines, e.g. mains
        hum; default: found) are the lab options. Returns the typed document:
        ``det.fundamental.sigma2``, ``det.modes[0].omega``...
        """
        return (yield core.detect(signal_id, w=w, t=t, dt=dt, method=method, quantity=quantity,
                                  start=start, notch=notch))  # fmt: skip

    @operation
    def predict(
        self,
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
    ) -> Flow[Prediction]:
        """``POST /v1/predictions``: mu* from a sweep table measured elsewhere.

        ``mu`` (increasing) with ``sigma2`` or ``omega`` (lists or numpy arrays; both only
        when they agree row by row, ``sigma2`` is then used, else :class:`InvalidInput` naming
        ``omega``), their standard deviations, ``w_static``; the options of ``snapwarn
        predict`` (``damping``, ``transition``, ``a``: the time exponent of the law to fit,
        > 0, alone or with ``transition``) and the interval's ``level`` (0.95). ``omega_unit``
        ``"Hz"``, ``"kHz"``, ``"MHz"`` or ``"rpm"`` reads the rates as ``2 pi f`` rad/s (the
        CLI's ``omega [Hz]`` header). Returns the typed document that ``snapwarn predict
        --json`` prints: ``p.mu_star``, ``p.mu_star_interval``, ``p.transition``, ``p.flags``.
        """
        return (yield core.predict(
            mu, sigma2, sigma2_std=sigma2_std, omega=omega, omega_std=omega_std,
            omega_unit=omega_unit, w_static=w_static, w_static_std=w_static_std,
            damping=damping, transition=transition, a=a, level=level,
        ))  # fmt: skip

    @operation
    def create_sweep(
        self,
        measurements: Iterable[Any] | None = None,
        *,
        simulate: Mapping[str, Any] | None = None,
        name: str | None = None,
        control: str | None = None,
        unit: str | None = None,
        band: tuple[float, float] | None = None,
        notch: Any = None,
        exclude: Iterable[str] = (),
    ) -> Flow[Sweep]:
        """``POST /v1/sweeps``: ``[(signal_id, control_value), ...]`` or ``simulate={...}``;
        ``control``/``unit``: the name and unit of the control the signals were recorded along
        (recorded sweeps only). Detector options (recorded sweeps): ``band`` (the
        fundamental's sqrt|sigma2| range), ``notch`` (line frequencies), ``exclude`` (signal
        ids left out, listed as set aside); per record, a measurement may be a mapping with
        ``quantity``, ``start``, ``notch``, ``exclude``."""
        return (
            yield core.create_sweep(
                measurements, simulate=simulate, name=name, control=control, unit=unit,
                band=band, notch=notch, exclude=exclude,
            )
        )  # fmt: skip

    @operation
    def get_sweep(self, sweep_id: str) -> Flow[Sweep]:
        """``GET /v1/sweeps/{id}``."""
        return (yield core.get_sweep(sweep_id))

    @operation
    def sweep_plot(self, sweep_id: str, *, format: str = "png") -> Flow[bytes]:
        """The T(mu) chart of a finished sweep (PNG or SVG bytes)."""
        return (yield core.sweep_plot(sweep_id, format=format))

    @operation
    def get_job(self, job_id: str) -> Flow[Job]:
        """``GET /v1/jobs/{id}``."""
        return (yield core.get_job(job_id))

    @operation
    def wait(
        self,
        job: Any,
        *,
        progress: bool = False,
        timeout: float | None = None,
        poll: float = 0.25,
        raise_on_failure: bool = True,
    ) -> Flow[Any]:
        """Poll a job (or a Sweep / SimulationResult / id) until it ends (``progress=True``
        draws a bar on stderr).

        Returns the finished Job, or the refreshed Sweep when given a Sweep. Raises
        :class:`JobFailed` if it failed (unless ``raise_on_failure=False``) and
        :class:`WaitTimeout` after ``timeout`` seconds.
        """
        return (yield from core.wait_flow(job, progress=progress, timeout=timeout, poll=poll,
                                     raise_on_failure=raise_on_failure))  # fmt: skip


class Client(Api):
    """Blocking SDK client.

    >>> with Client("http://127.0.0.1:8000") as c:       # doctest: +SKIP
    ...     sig = c.upload_file("run.csv", control_value=1.2)
    ...     doc = c.detect(sig.id)
    """

    _is_async: ClassVar[Literal[False]] = False

    def __init__(
        self,
        base_url: str,
        api_key: str | None = None,
        timeout: float = 60.0,
        *,
        transport: httpx2.BaseTransport | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        self._http = httpx2.Client(base_url=base_url, timeout=timeout, transport=transport,
                                   headers=_headers(api_key, headers))  # fmt: skip

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self, call: core.Call) -> Any:
        try:
            r = self._http.request(**core.request_args(call))
        except httpx2.TransportError as exc:  # no answer: connection, timeout, protocol
            raise TransportFailed(f"{call.method} {call.path}: {exc!r}") from exc
        core.raise_for_problem(r)
        return call.parse(r)

    def live_sweep(
        self, name: str | None = None, *, control: str = "mu", unit: str | None = None,
        sweep_id: str | None = None, **options: Any,
    ) -> LiveSweep:  # fmt: skip
        """Open a live sweep (``POST /v1/sweeps``, mode live; ``margin=``, ``step=``,
        ``budget=``, ``target_width=``, ``control_resolution=``, ``method=``, and the
        detector's ``band=`` and ``notch=`` for every record), or attach to ``sweep_id``:
        ``add``, ``events``, ``close``."""
        call = live.open_or_attach(name, control, unit, sweep_id, options)
        return LiveSweep(self, self._run(call))


class AsyncClient(Api):
    """asyncio SDK client; the same methods as :class:`Client`, awaitable."""

    _is_async: ClassVar[Literal[True]] = True

    def __init__(
        self,
        base_url: str,
        api_key: str | None = None,
        timeout: float = 60.0,
        *,
        transport: httpx2.AsyncBaseTransport | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        self._http = httpx2.AsyncClient(base_url=base_url, timeout=timeout, transport=transport,
                                        headers=_headers(api_key, headers))  # fmt: skip

    async def aclose(self) -> None:
        await self._http.aclose()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def _run(self, call: core.Call) -> Any:
        try:
            r = await self._http.request(**core.request_args(call))
        except httpx2.TransportError as exc:  # no answer: connection, timeout, protocol
            raise TransportFailed(f"{call.method} {call.path}: {exc!r}") from exc
        core.raise_for_problem(r)
        return call.parse(r)

    async def live_sweep(
        self, name: str | None = None, *, control: str = "mu", unit: str | None = None,
        sweep_id: str | None = None, **options: Any,
    ) -> AsyncLiveSweep:  # fmt: skip
        """See :meth:`Client.live_sweep`."""
        call = live.open_or_attach(name, control, unit, sweep_id, options)
        return AsyncLiveSweep(self, await self._run(call))
