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
