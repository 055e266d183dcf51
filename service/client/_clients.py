"""``Client`` (blocking) and ``AsyncClient`` (asyncio) over httpx2."""

from __future__ import annotations

import asyncio
import os
import time
from collections.abc import Iterable, Mapping
from typing import Any

import httpx2

from service.client import _core as core
from service.client import live
from service.client.atlases import AsyncAtlasMethods, AtlasMethods
from service.client.errors import JobFailed, TransportFailed, WaitTimeout
from service.client.live import AsyncLiveSweep, LiveSweep
from service.schemas import (
    Detection,
    Health,
    Job,
    JobPage,
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


class Client(AtlasMethods):
    """Blocking SDK client.

    >>> with Client("http://127.0.0.1:8000") as c:       # doctest: +SKIP
    ...     sig = c.upload_file("run.csv", control_value=1.2)
    ...     doc = c.detect(sig.id)
    """

    def __init__(
        self,
        base_url: str,
        api_key: str | None = None,
        timeout: float = 60.0,
        *,
        transport: httpx2.BaseTransport | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        self._http = httpx2.Client(
            base_url=base_url,
            timeout=timeout,
            transport=transport,
            headers=_headers(api_key, headers),
        )

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self, call: core.Call) -> Any:
        try:
            r = self._http.request(
                call.method,
                call.path,
                params=call.params,
                content=call.content,
                files=call.files,
                data=call.data,
                headers=call.headers or None,
            )
        except httpx2.TransportError as exc:  # no answer: connection, timeout, protocol
            raise TransportFailed(f"{call.method} {call.path}: {exc!r}") from exc
        core.raise_for_problem(r)
        return call.parse(r)

    # --- resources ---------------------------------------------------------------------------
    def health(self) -> Health:
        """``GET /healthz``."""
        return self._run(core.health())

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
    ) -> SignalMeta:
        """``POST /v1/signals`` (JSON): samples ``w`` with their times ``t`` or step ``dt``.

        ``control`` is ``{"name", "value", "unit"}``; ``resample`` interpolates non-uniform
        times onto a uniform grid (else the server answers 422 naming the worst step).
        """
        return self._run(core.upload_signal(
            w, t=t, dt=dt, t0=t0, unit=unit, value_unit=value_unit, control=control,
            metadata=metadata, name=name, resample=resample,
        ))  # fmt: skip

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
    ) -> SignalMeta:
        """``POST /v1/signals`` (multipart): a path or bytes (CSV, NPY, NPZ, WAV, MAT).

        ``dt`` gives the step of a file without times (1-D .npy, one-column CSV); the server
        refuses it for a file that has times. See ``service.recordings`` for the layouts.
        """
        return self._run(core.upload_file(
            file, filename=filename, format=format, dt=dt, t0=t0, column=column,
            time_column=time_column, channel=channel, resample=resample, unit=unit,
            value_unit=value_unit, control_name=control_name, control_value=control_value,
            control_unit=control_unit, metadata=metadata, name=name,
        ))  # fmt: skip

    def list_signals(self, *, limit: int = 50, offset: int = 0) -> SignalPage:
        """``GET /v1/signals``: a page of signals, newest first."""
        return self._run(core.list_signals(limit=limit, offset=offset))

    def list_jobs(
        self,
        *,
        status: str | None = None,
        kind: str | None = None,
        limit: int = 50,
        offset: int = 0,
    ) -> JobPage:
        """``GET /v1/jobs``: a page of jobs, newest first (filtered by status and kind)."""
        return self._run(core.list_jobs(status=status, kind=kind, limit=limit, offset=offset))

    def get_signal(self, signal_id: str) -> SignalMeta:
        """``GET /v1/signals/{id}``."""
        return self._run(core.get_signal(signal_id))

    def signal_data(self, signal_id: str, *, as_numpy: bool | None = None) -> tuple[Any, Any]:
        """``(t, w)`` exactly as stored: numpy arrays where numpy is installed, else lists."""
        return self._run(core.signal_data(signal_id, as_numpy=as_numpy))

    def download_signal(self, signal_id: str, *, format: str = "csv") -> bytes:
        """The stored samples as a CSV, NPY or JSON file's bytes."""
        return self._run(core.download_signal(signal_id, format=format))

    def delete_signal(self, signal_id: str) -> None:
        """``DELETE /v1/signals/{id}``."""
        return self._run(core.delete_signal(signal_id))

    def signal_plot(self, signal_id: str) -> bytes:
        """PNG chart of a signal."""
        return self._run(core.signal_plot(signal_id))

    def simulate(self, **scene: Any) -> SimulationResult:
        """``POST /v1/simulations``: ``.signal`` at once, or ``.job`` to :meth:`wait` for."""
        return self._run(core.simulate(**scene))

    def snap(self, **request: Any) -> Any:
        """``POST /v1/snaps``: ``.snap`` at once (normal form), or ``.job`` to :meth:`wait` for
        (its result is the snap document)."""
        return self._run(core.snap(**request))

    def detect(
        self,
        signal_id: str | None = None,
        *,
        w: Any = None,
        t: Any = None,
        dt: float | None = None,
        method: str = "auto",
    ) -> Detection:
        """``POST /v1/detections``: a stored signal's id, or ``w`` with ``t`` or ``dt``.

        Returns the typed document: ``det.fundamental.sigma2``, ``det.modes[0].omega``...
        """
        return self._run(core.detect(signal_id, w=w, t=t, dt=dt, method=method))

    def create_sweep(
        self,
        measurements: Iterable[Any] | None = None,
        *,
        simulate: Mapping[str, Any] | None = None,
        name: str | None = None,
    ) -> Sweep:
        """``POST /v1/sweeps``: ``[(signal_id, control_value), ...]`` or ``simulate={...}``."""
        return self._run(core.create_sweep(measurements, simulate=simulate, name=name))

    def get_sweep(self, sweep_id: str) -> Sweep:
        """``GET /v1/sweeps/{id}``."""
        return self._run(core.get_sweep(sweep_id))

    def live_sweep(
        self, name: str | None = None, *, control: str = "mu", unit: str | None = None,
        sweep_id: str | None = None, **options: Any,
    ) -> LiveSweep:  # fmt: skip
        """Open a live sweep (``POST /v1/sweeps``, mode live; ``margin=``, ``step=``,
        ``budget=``, ``target_width=``), or attach to ``sweep_id``: ``add``, ``events``,
        ``close``."""
        if sweep_id is not None:
            return LiveSweep(self, self.get_sweep(sweep_id))
        call = live.create_live_sweep(name, control=control, unit=unit, **options)
        return LiveSweep(self, self._run(call))

    def sweep_plot(self, sweep_id: str, *, format: str = "png") -> bytes:
        """The T(mu) chart of a finished sweep (PNG or SVG bytes)."""
        return self._run(core.sweep_plot(sweep_id, format=format))

    def get_job(self, job_id: str) -> Job:
        """``GET /v1/jobs/{id}``."""
        return self._run(core.get_job(job_id))

    def wait(
        self,
        job: Any,
        *,
        progress: bool = False,
        timeout: float | None = None,
        poll: float = 0.25,
        raise_on_failure: bool = True,
    ) -> Any:
        """Poll a job (or a Sweep / SimulationResult / id) until it ends (``progress=True``
        draws a bar on stderr).

        Returns the finished Job, or the refreshed Sweep when given a Sweep. Raises
        :class:`JobFailed` if it failed (unless ``raise_on_failure=False``) and
        :class:`WaitTimeout` after ``timeout`` seconds.
        """
        jid = core.job_id_of(job)
        bar = core.Bar(progress, f"job {jid[:8]}")
        deadline = None if timeout is None else time.monotonic() + timeout
        try:
            while True:
                j = self.get_job(jid)
                bar.update(j)
                if j.done:
                    break
                if deadline is not None and time.monotonic() > deadline:
                    raise WaitTimeout(f"job {jid} still {j.status} after {timeout} s")
                time.sleep(poll)
        finally:
            bar.close()
        if j.status == "failed" and raise_on_failure:
            raise JobFailed(j)
        return self.get_sweep(job.id) if isinstance(job, Sweep) else j


class AsyncClient(AsyncAtlasMethods):
    """asyncio SDK client; the same methods as :class:`Client`, awaitable."""

    def __init__(
        self,
        base_url: str,
        api_key: str | None = None,
        timeout: float = 60.0,
        *,
        transport: httpx2.AsyncBaseTransport | None = None,
        headers: dict[str, str] | None = None,
    ) -> None:
        self._http = httpx2.AsyncClient(
            base_url=base_url,
            timeout=timeout,
            transport=transport,
            headers=_headers(api_key, headers),
        )

    async def aclose(self) -> None:
        await self._http.aclose()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.aclose()

    async def _run(self, call: core.Call) -> Any:
        try:
            r = await self._http.request(
                call.method,
                call.path,
                params=call.params,
                content=call.content,
                files=call.files,
                data=call.data,
                headers=call.headers or None,
            )
        except httpx2.TransportError as exc:  # no answer: connection, timeout, protocol
            raise TransportFailed(f"{call.method} {call.path}: {exc!r}") from exc
        core.raise_for_problem(r)
        return call.parse(r)

    async def health(self) -> Health:
        return await self._run(core.health())

    async def upload_signal(
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
    ) -> SignalMeta:
        """See :meth:`Client.upload_signal`."""
        return await self._run(core.upload_signal(
            w, t=t, dt=dt, t0=t0, unit=unit, value_unit=value_unit, control=control,
            metadata=metadata, name=name, resample=resample,
        ))  # fmt: skip

    async def upload_file(
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
    ) -> SignalMeta:
        """See :meth:`Client.upload_file`."""
        return await self._run(core.upload_file(
            file, filename=filename, format=format, dt=dt, t0=t0, column=column,
            time_column=time_column, channel=channel, resample=resample, unit=unit,
            value_unit=value_unit, control_name=control_name, control_value=control_value,
            control_unit=control_unit, metadata=metadata, name=name,
        ))  # fmt: skip

    async def list_signals(self, *, limit: int = 50, offset: int = 0) -> SignalPage:
        return await self._run(core.list_signals(limit=limit, offset=offset))

    async def list_jobs(
        self,
        *,
        status: str | None = None,
        kind: str | None = None,
        limit: int = 50,
        offset: int = 0,
    ) -> JobPage:
        """See :meth:`Client.list_jobs`."""
        return await self._run(
            core.list_jobs(status=status, kind=kind, limit=limit, offset=offset)
        )

    async def get_signal(self, signal_id: str) -> SignalMeta:
        return await self._run(core.get_signal(signal_id))

    async def signal_data(self, signal_id: str, *, as_numpy: bool | None = None) -> tuple[Any, Any]:
        return await self._run(core.signal_data(signal_id, as_numpy=as_numpy))

    async def download_signal(self, signal_id: str, *, format: str = "csv") -> bytes:
        return await self._run(core.download_signal(signal_id, format=format))

    async def delete_signal(self, signal_id: str) -> None:
        return await self._run(core.delete_signal(signal_id))

    async def signal_plot(self, signal_id: str) -> bytes:
        return await self._run(core.signal_plot(signal_id))

    async def simulate(self, **scene: Any) -> SimulationResult:
        return await self._run(core.simulate(**scene))

    async def snap(self, **request: Any) -> Any:
        return await self._run(core.snap(**request))

    async def detect(
        self,
        signal_id: str | None = None,
        *,
        w: Any = None,
        t: Any = None,
        dt: float | None = None,
        method: str = "auto",
    ) -> Detection:
        """See :meth:`Client.detect`."""
        return await self._run(core.detect(signal_id, w=w, t=t, dt=dt, method=method))

    async def create_sweep(
        self,
        measurements: Iterable[Any] | None = None,
        *,
        simulate: Mapping[str, Any] | None = None,
        name: str | None = None,
    ) -> Sweep:
        """See :meth:`Client.create_sweep`."""
        return await self._run(core.create_sweep(measurements, simulate=simulate, name=name))

    async def get_sweep(self, sweep_id: str) -> Sweep:
        return await self._run(core.get_sweep(sweep_id))

    async def live_sweep(
        self, name: str | None = None, *, control: str = "mu", unit: str | None = None,
        sweep_id: str | None = None, **options: Any,
    ) -> AsyncLiveSweep:  # fmt: skip
        """See :meth:`Client.live_sweep`."""
        if sweep_id is not None:
            return AsyncLiveSweep(self, await self.get_sweep(sweep_id))
        call = live.create_live_sweep(name, control=control, unit=unit, **options)
        return AsyncLiveSweep(self, await self._run(call))

    async def sweep_plot(self, sweep_id: str, *, format: str = "png") -> bytes:
        return await self._run(core.sweep_plot(sweep_id, format=format))

    async def get_job(self, job_id: str) -> Job:
        return await self._run(core.get_job(job_id))

    async def wait(
        self,
        job: Any,
        *,
        progress: bool = False,
        timeout: float | None = None,
        poll: float = 0.25,
        raise_on_failure: bool = True,
    ) -> Any:
        """See :meth:`Client.wait`."""
        jid = core.job_id_of(job)
        bar = core.Bar(progress, f"job {jid[:8]}")
        deadline = None if timeout is None else time.monotonic() + timeout
        try:
            while True:
                j = await self.get_job(jid)
                bar.update(j)
                if j.done:
                    break
                if deadline is not None and time.monotonic() > deadline:
                    raise WaitTimeout(f"job {jid} still {j.status} after {timeout} s")
                await asyncio.sleep(poll)
        finally:
            bar.close()
        if j.status == "failed" and raise_on_failure:
            raise JobFailed(j)
        return await self.get_sweep(job.id) if isinstance(job, Sweep) else j
