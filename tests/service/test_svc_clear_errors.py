"""The audit's causes of 500 and silent acceptances: each a 4xx naming the field.

(61,267 schemathesis cases and a 339-case corpus found them: a normal-form simulation whose
dt or duration leaves one sample (IndexError), a Cosserat snap of slenderness 3e-93
(ArpackError), a NUL in a JSON name or a live sweep's control name (a 500 on PostgreSQL,
then silently replaced), a simulated sweep with damping 1e300 failing in its job.)
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.anyio

CASES = [
    ("normal-form dt past the duration", "/v1/simulations",
     {"model": "normal-form", "dt": 911.7}, "dt"),
    ("normal-form duration 1e-5", "/v1/simulations",
     {"model": "normal-form", "duration": 1e-5, "end_shortening": 5e-324}, "duration"),
    ("cosserat snap slenderness 3e-93", "/v1/snaps",
     {"model": "cosserat", "slenderness": 3e-93, "dmu": 0.01}, "slenderness"),
    ("NUL in a signal's name", "/v1/signals",
     {"dt": 0.1, "w": [1.0, 2.0, 3.0], "name": "a\u0000b"}, "name"),
    ("NUL in a live sweep's control name", "/v1/sweeps",
     {"mode": "live", "control": {"name": "m\u0000u"}}, "name"),
    ("simulated sweep damping 1e300", "/v1/sweeps",
     {"simulate": {"damping": 1e300}}, "simulate.damping"),
]  # fmt: skip


@pytest.mark.parametrize(("label", "path", "body", "field"), CASES, ids=[c[0] for c in CASES])
async def test_each_is_a_4xx_naming_the_field(asgi, label, path, body, field) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.post(path, json=body)
    assert r.status_code == 422, (label, r.status_code, r.text[:300])
    fields = [e.get("field", "") for e in r.json().get("errors", [])]
    assert any(f == field or f.endswith("." + field) for f in fields), (label, fields)


async def test_a_nul_in_a_large_streamed_body_is_refused(asgi) -> None:  # noqa: ANN001
    """Past the size read whole (64 KiB), the body is checked as it streams: still a 4xx."""
    _, client = asgi
    body = '{"dt": 0.1, "w": [' + ",".join(["1.5"] * 300_000) + '], "name": "x\\u0000"}'
    r = await client.post("/v1/signals", content=body.encode(),
                          headers={"content-type": "application/json"})  # fmt: skip
    assert 400 <= r.status_code < 500, r.text[:300]


SNAP = {"model": "cosserat", "actuation": "asymmetric", "dmu": 0.01, "damping": 2e-4,
        "end_shortening": 1e-2, "slenderness": 1e-3, "poisson": 0.5, "rtol": None,
        "elements": None}  # fmt: skip


def _snap_refusal(**kw: object) -> object:
    from service.api.routers.snaps import check_snap
    from service.api.settings import Settings

    try:
        check_snap(SNAP | kw, Settings())
    except Exception as exc:  # noqa: BLE001 - the problem is the answer
        return exc
    return None


def test_a_rod_snap_over_the_work_budget_is_refused_naming_the_duration() -> None:
    """The audit's reproducer: duration 500 ran 4000 steps of 0.125 (the rod's own step is
    5.5e-4), Newton diverged and a 5-sample record 'succeeded'. Now its cost at the rod's step
    (4000 x 227 steps x 290 elements) is over SNAPWARN_MAX_SIM_WORK: 422 on duration, with the
    longest duration that fits, which the door then takes (and 10 % more it refuses)."""
    import re

    from service.api.problems import ApiProblem

    exc = _snap_refusal(duration=500.0)
    assert isinstance(exc, ApiProblem) and exc.status == 422, exc
    assert [e["field"] for e in exc.errors] == ["duration"], exc.errors
    assert "SNAPWARN_MAX_SIM_WORK" in exc.detail and "elements=290" in exc.detail, exc.detail
    fits = float(re.search(r"duration <= ([0-9.e+-]+)", exc.detail).group(1))
    assert 10 < fits < 500, exc.detail
    assert _snap_refusal(duration=fits * 0.999) is None
    assert isinstance(_snap_refusal(duration=fits * 1.1), ApiProblem)
    assert _snap_refusal() is None  # the default duration (4.4) fits: 2 steps a sample


async def test_the_snap_door_refuses_it_before_any_job(asgi) -> None:  # noqa: ANN001
    _, client = asgi
    before = (await client.get("/v1/jobs", params={"limit": 500})).json()["total"]
    r = await client.post("/v1/snaps", json={"model": "cosserat", "dmu": 0.01, "duration": 500})
    assert r.status_code == 422, r.text[:300]
    assert [e["field"] for e in r.json()["errors"]] == ["duration"], r.json()
    assert (await client.get("/v1/jobs", params={"limit": 500})).json()["total"] == before


def test_a_diverged_rod_is_an_error_naming_the_duration_not_a_short_record() -> None:
    import numpy as np

    from sim.errors import ParameterError
    from sim.snap import _check_resolved

    _check_resolved("done", np.arange(5.0), 4.0, 0.1)
    with pytest.raises(ParameterError) as exc:
        _check_resolved("diverged", np.arange(5) * 0.125, 500.0, 0.0156)
    assert exc.value.parameter == "duration" and "diverged at t=0.5" in str(exc.value)


@pytest.mark.slow
def test_the_rod_steps_at_its_own_step_within_a_coarse_record() -> None:
    """``every``: a record sampled every 2e-3 by steps of 1e-3 is the 1e-3 run's record at
    every other sample (the same steps, only fewer of them recorded)."""
    import numpy as np

    from sim.cosserat import snap_through

    coarse = snap_through(0.01, elements=16, duration=1.0, dt=2e-3, every=2)
    fine = snap_through(0.01, elements=16, duration=1.0, dt=1e-3, mu_star=coarse.mu_star)
    assert coarse.info["stop"] == fine.info["stop"] == "done"
    assert coarse.info["dt"] == fine.info["dt"] and coarse.t.size == 501
    np.testing.assert_allclose(coarse.t, fine.t[::2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(coarse.w_mid, fine.w_mid[::2], rtol=0, atol=1e-12)
