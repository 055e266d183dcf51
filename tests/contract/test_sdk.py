"""The SDK speaks the typed contract: typed results, keyword signatures, its own errors."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from service.client import AsyncClient, Client, SnapwarnError, TransportFailed
from service.schemas import Detection

pytestmark = pytest.mark.anyio


async def test_results_are_the_typed_models(api) -> None:  # noqa: ANN001
    t = 0.01 * np.arange(2000)
    w = np.exp(-0.05 * t) * np.cos(8.0 * t) + 1e-4 * np.random.default_rng(1).normal(size=t.size)
    async with AsyncClient("http://asgi", transport=api._transport) as sdk:
        det = await sdk.detect(w=w, dt=0.01)
        assert isinstance(det, Detection)
        assert det.fundamental is not None and det.modes[0].sigma2 == det.fundamental.sigma2
        assert det.fundamental.omega == pytest.approx(8.0, rel=1e-4)
        sig = await sdk.upload_signal(w, t=t, name="ringdown")
        assert (await sdk.detect(sig.id)) == det  # stored or inline: one document


def test_transport_errors_are_snapwarn_errors() -> None:
    with Client("http://127.0.0.1:9", timeout=2.0) as c:  # discard port: nobody answers
        with pytest.raises(TransportFailed) as e:
            c.health()
    assert isinstance(e.value, SnapwarnError) and e.value.__cause__ is not None


def test_keyword_signatures_and_quiet_waits() -> None:
    open_ended = {"simulate", "snap", "live_sweep"}  # scene/request fields pass through
    for cls in (Client, AsyncClient):
        for name, fn in inspect.getmembers(cls, inspect.isfunction):
            if name.startswith("_") or name in open_ended or fn.__module__ != cls.__module__:
                continue  # (the atlas and live mixins have their own modules)
            kinds = {p.kind for p in inspect.signature(fn).parameters.values()}
            assert inspect.Parameter.VAR_KEYWORD not in kinds, f"{cls.__name__}.{name}"
        assert inspect.signature(cls.wait).parameters["progress"].default is False
