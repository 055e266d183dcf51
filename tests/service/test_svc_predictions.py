"""``POST /v1/predictions``: a sweep table measured elsewhere through the three doors.

The exact Euler-beam sigma^2 near the asymmetric fold, with 1e-4 relative noise, goes through
``snapwarn predict FILE --json``, a real uvicorn on loopback and the SDK: one document (mu*,
its interval, the transition, the flags), compared as JSON. Bad tables are 422 problems naming
the field and the value (the numerics' own names where they judge), never a 5xx.
"""

from __future__ import annotations

import asyncio
import functools
import io
import json
import math
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path
from typing import Any

import httpx2
import numpy as np
import pytest
from _svc_helpers import test_settings

from service.api import Settings, create_app

NOISE = 1e-4


@functools.cache
def _beam_table() -> dict[str, Any]:
    """The exact asymmetric-beam sigma^2 at 12 points approaching its fold, noisy (1e-4)."""
    from sim.euler_beam import bifurcation, spectrum

    b = bifurcation("asymmetric")
    mu = b.mu_star - np.geomspace(1.0, 1e-3, 12)
    s2 = np.array([spectrum("asymmetric", m, "U_A", modes=1).sigma2[0] for m in mu])
    rng = np.random.default_rng(7)
    noisy = s2 * (1.0 + NOISE * rng.standard_normal(s2.size))
    return {"mu": mu, "sigma2": noisy, "sigma2_std": NOISE * np.abs(s2), "mu_star": b.mu_star}


@pytest.fixture(scope="module")
def beam() -> dict[str, Any]:
    pytest.importorskip("sim.euler_beam")
    return _beam_table()


def _write(path: Path, cols: dict[str, Any]) -> Path:
    """A CSV table: a header of the column names (units in brackets), floats written exactly."""
    n = len(next(iter(cols.values())))
    rows = [",".join(cols)] + [",".join(repr(float(v[i])) for v in cols.values()) for i in range(n)]
    path.write_text("\n".join(rows) + "\n")
    return path


def _cli(*argv: str) -> tuple[int, Any]:
    """``snapwarn ARGV`` in-process: the exit code and the stdout JSON document."""
    from service.cli import main

    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        rc = main(list(argv))
    return rc, json.loads(out.getvalue())


def _post(url: str, body: dict[str, Any]) -> httpx2.Response:
    content = json.dumps(body, allow_nan=True).encode()  # NaN literals: the server names them
    return httpx2.post(
        url + "/v1/predictions",
        content=content,
        headers={"content-type": "application/json"},
        timeout=60,
    )


def _lists(table: dict[str, Any], *names: str) -> dict[str, list[float]]:
    return {k: [float(x) for x in table[k]] for k in names}


# --- the three doors --------------------------------------------------------------------------
def test_a_beam_table_gives_one_document_through_cli_api_and_sdk(
    beam, live_server, tmp_path
) -> None:  # noqa: ANN001
    from service.client import Client
    from service.schemas import Prediction

    path = _write(tmp_path / "fold.csv", {k: beam[k] for k in ("mu", "sigma2", "sigma2_std")})
    rc, cli_doc = _cli("predict", str(path), "--json")
    assert rc == 0, cli_doc
    r = _post(live_server.url, _lists(beam, "mu", "sigma2", "sigma2_std"))
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/json")
    api_doc = r.json()
    with Client(live_server.url) as sdk:
        pred = sdk.predict(beam["mu"], beam["sigma2"], sigma2_std=beam["sigma2_std"])
    assert isinstance(pred, Prediction)
    sdk_doc = json.loads(pred.model_dump_json())
    assert cli_doc == api_doc == sdk_doc
    assert set(api_doc) == set(Prediction.model_fields)
    # and it is a prediction of the fold: mu*, its interval, the transition
    lo, hi = api_doc["mu_star_interval"]
    assert lo <= beam["mu_star"] <= hi
    assert api_doc["mu_star"] == pytest.approx(beam["mu_star"], abs=1e-5)
    assert api_doc["transition"] == "saddle-node"
    assert [f["code"] for f in api_doc["flags"]] == [f["code"] for f in cli_doc["flags"]]


def test_rates_in_hz_with_options_give_the_clis_document(beam, live_server, tmp_path) -> None:  # noqa: ANN001
    """``omega [Hz]`` columns and --damping/--transition: the CLI's conversion (2 pi f) and
    options, the same floats through ``omega_unit`` and the body's options."""
    from service.client import AsyncClient

    f = np.sqrt(-beam["sigma2"]) / (2.0 * math.pi)
    f_std = 1e-4 * f
    w = 0.1 + 0.01 * np.sqrt(beam["mu_star"] - beam["mu"])
    cols = {"mu": beam["mu"], "omega [Hz]": f, "omega_std [Hz]": f_std, "w_static": w}
    path = _write(tmp_path / "rates.csv", cols)
    rc, cli_doc = _cli(
        "predict", str(path), "--json", "--damping", "0.25", "--transition", "saddle-node"
    )
    assert rc == 0, cli_doc
    body = {"mu": beam["mu"].tolist(), "omega": f.tolist(), "omega_std": f_std.tolist(),
            "omega_unit": "hz", "w_static": w.tolist(), "damping": 0.25,
            "transition": "saddle-node"}  # fmt: skip
    r = _post(live_server.url, body)
    assert r.status_code == 200, r.text
    assert r.json() == cli_doc
    # a lab's table of the frequency itself (no omega column): the same floats, one document
    freq = _write(tmp_path / "freq.csv", {"mu": beam["mu"], "freq_Hz": f, "freq_std": f_std,
                                          "w_static": w})  # fmt: skip
    rc, freq_doc = _cli(
        "predict", str(freq), "--json", "--damping", "0.25", "--transition", "saddle-node"
    )
    assert rc == 0 and freq_doc == cli_doc, freq_doc

    async def via_sdk() -> Any:
        async with AsyncClient(live_server.url) as sdk:
            return await sdk.predict(
                beam["mu"], omega=f, omega_std=f_std, omega_unit="Hz", w_static=w,
                damping=0.25, transition="saddle-node",
            )  # fmt: skip

    assert json.loads(asyncio.run(via_sdk()).model_dump_json()) == cli_doc
    # the unit matters: the same numbers read as rad/s are another document
    r = _post(live_server.url, {**body, "omega_unit": "rad/s"})
    assert r.status_code == 200 and r.json() != cli_doc


def test_numerics_refusals_name_the_same_field_and_value_as_the_cli(live_server, tmp_path) -> None:  # noqa: ANN001
    tables = {
        "decreasing mu": {"mu": [2.0, 1.0, 0.0], "sigma2": [-3.0, -2.0, -1.0]},
        "positive sigma2": {"mu": [0.0, 1.0, 2.0], "sigma2": [-3.0, 2.0, -1.0]},
        "two points": {"mu": [0.0, 1.0], "sigma2": [-3.0, -2.0]},
        "zero omega": {"mu": [0.0, 1.0, 2.0], "omega": [3.0, 0.0, 1.0]},
    }
    for name, cols in tables.items():
        rc, cli_doc = _cli("predict", str(_write(tmp_path / "bad.csv", cols)), "--json")
        assert rc == 2, name
        r = _post(live_server.url, cols)
        assert r.status_code == 422, (name, r.text)
        assert r.headers["content-type"].startswith("application/problem+json")
        err = r.json()["errors"][0]
        assert (err["field"], err["value"]) == (cli_doc["field"], cli_doc["value"]), name


def _custom_table() -> dict[str, Any]:
    """A law of exponent a = 0.35 (|sigma2| ~ x^0.7, with a correction) at 14 points
    approaching mu* = 1.78, 1e-4 relative noise."""
    x = np.geomspace(1.0, 1e-3, 14)
    s = 12.0 * x**0.7 * (1 + 0.3 * x)
    rng = np.random.default_rng(5)
    return {"mu": 1.78 - x, "sigma2": -s * (1 + NOISE * rng.standard_normal(x.size)),
            "sigma2_std": NOISE * s}  # fmt: skip


@pytest.mark.parametrize(
    "options", [{"a": 0.35}, {"transition": "pitchfork", "a": 0.35}], ids=["a", "pitchfork-a"]
)
def test_a_custom_exponent_gives_one_mu_star_through_cli_api_and_sdk(
    live_server, tmp_path, options
) -> None:  # noqa: ANN001
    """``--a``, ``"a"`` and ``a=``: the same law, the same document (before: the CLI had no
    --a, the body refused the field, the SDK had no argument, and the numerics' law named
    "custom" could not be written as a document)."""
    from service.client import Client

    t = _custom_table()
    path = _write(tmp_path / "custom.csv", t)
    argv = [f"--{k}={v}" for k, v in options.items()]
    rc, cli_doc = _cli("predict", str(path), "--json", *argv)
    assert rc == 0, cli_doc
    r = _post(live_server.url, {**_lists(t, "mu", "sigma2", "sigma2_std"), **options})
    assert r.status_code == 200, r.text
    with Client(live_server.url) as sdk:
        pred = sdk.predict(t["mu"], t["sigma2"], sigma2_std=t["sigma2_std"], **options)
    assert cli_doc == r.json() == json.loads(pred.model_dump_json())
    assert cli_doc["a"] == 0.35 and cli_doc["method"] == "profile-likelihood"
    lo, hi = cli_doc["mu_star_interval"]
    assert lo <= 1.78 <= hi and abs(cli_doc["mu_star"] - 1.78) < 1e-5
    if "transition" in options:
        assert cli_doc["transition"] == "pitchfork"
    else:
        assert cli_doc["transition"] == "custom"
        assert cli_doc["probabilities"] == {"custom": 1.0}
    # the exponent matters: the classified law is another document
    assert _cli("predict", str(path), "--json")[1]["a"] != 0.35


@pytest.mark.parametrize(
    "options, value",
    [({"a": -0.5}, -0.5), ({"a": 0.0}, 0.0), ({"transition": "saddle-node", "a": 0.3}, 0.3)],
)
def test_a_bad_exponent_is_named_alike_by_the_three_doors(
    live_server, tmp_path, options, value
) -> None:  # noqa: ANN001
    from service.client import Client, InvalidInput

    t = _custom_table()
    path = _write(tmp_path / "custom.csv", t)
    rc, cli_doc = _cli("predict", str(path), "--json", *[f"--{k}={v}" for k, v in options.items()])
    assert rc == 2 and (cli_doc["field"], cli_doc["value"]) == ("a", value), cli_doc
    r = _post(live_server.url, {**_lists(t, "mu", "sigma2"), **options})
    assert r.status_code == 422, r.text
    err = r.json()["errors"][0]
    assert (err["field"], err["value"]) == ("a", value)
    assert f"a={value!r}" in err["message"]
    with Client(live_server.url) as sdk, pytest.raises(InvalidInput) as e:
        sdk.predict(t["mu"], t["sigma2"], **options)
    assert (e.value.field, e.value.value) == ("a", value)


def test_sigma2_and_omega_together_through_the_three_doors(beam, live_server, tmp_path) -> None:  # noqa: ANN001
    """A table with both columns: the sigma2 document when they agree; a refusal naming
    ``omega``, the worst row and its rate when they do not (before: the CLI used sigma2 and
    ignored omega, the API refused both columns naming sigma2)."""
    from service.client import Client, InvalidInput

    om = np.sqrt(-beam["sigma2"])
    cols = {"mu": beam["mu"], "sigma2": beam["sigma2"], "sigma2_std": beam["sigma2_std"],
            "omega": om, "omega_std": beam["sigma2_std"] / (2 * om)}  # fmt: skip
    ref = _cli("predict", str(_write(tmp_path / "s2.csv", {k: cols[k] for k in
                                                           ("mu", "sigma2", "sigma2_std")})),
               "--json")[1]  # fmt: skip
    rc, cli_doc = _cli("predict", str(_write(tmp_path / "both.csv", cols)), "--json")
    assert rc == 0, cli_doc
    r = _post(live_server.url, _lists(cols, *cols))
    assert r.status_code == 200, r.text
    with Client(live_server.url) as sdk:
        pred = sdk.predict(cols["mu"], cols["sigma2"], sigma2_std=cols["sigma2_std"],
                           omega=cols["omega"], omega_std=cols["omega_std"])  # fmt: skip
    assert cli_doc == r.json() == json.loads(pred.model_dump_json()) == ref
    # frequencies in Hz written as rad/s: every row disagrees
    bad = {"mu": beam["mu"], "sigma2": beam["sigma2"], "omega": om / (2 * math.pi)}
    path = _write(tmp_path / "bad.csv", bad)
    rc, cli_doc = _cli("predict", str(path), "--json")
    assert rc == 2 and cli_doc["field"] == "omega", cli_doc
    assert cli_doc["detail"].startswith(f"SWEEP {str(path)!r}: sigma2 and omega disagree")
    assert cli_doc["value"] in list(bad["omega"])
    r = _post(live_server.url, _lists(bad, *bad))
    assert r.status_code == 422, r.text
    err = r.json()["errors"][0]
    assert (err["field"], err["value"]) == ("omega", cli_doc["value"])
    assert "sigma2 and omega disagree" in err["message"]
    with Client(live_server.url) as sdk, pytest.raises(InvalidInput) as e:
        sdk.predict(bad["mu"], bad["sigma2"], omega=bad["omega"])
    assert (e.value.field, e.value.value) == ("omega", cli_doc["value"])


# --- bad bodies -------------------------------------------------------------------------------
MU = [0.0, 0.5, 0.8, 0.9]
S2 = [-4.0, -2.8, -1.8, -1.3]
BAD: list[tuple[str, dict[str, Any], str, Any]] = [
    ("lengths", {"mu": MU, "sigma2": S2[:3]}, "sigma2", 3),
    ("std length", {"mu": MU, "sigma2": S2, "sigma2_std": [1e-3] * 5}, "sigma2_std", 5),
    ("NaN mu", {"mu": [0.0, 0.5, math.nan, 0.9], "sigma2": S2}, "mu[2]", "NaN"),
    ("inf sigma2", {"mu": MU, "sigma2": [-4.0, -math.inf, -1.8, -1.3]}, "sigma2[1]", "-Infinity"),
    ("NaN damping", {"mu": MU, "sigma2": S2, "damping": math.nan}, "damping", "NaN"),
    # both columns, disagreeing (|sigma2| 1.3 against omega^2 1.21 on the worst row)
    ("both", {"mu": MU, "sigma2": S2, "omega": [2.0, 1.7, 1.3, 1.1]}, "omega", 1.1),
    (
        "omega_std beside disagreeing columns",
        {"mu": MU, "sigma2": S2, "omega": [2.0, 1.7, 1.3, 1.1], "omega_std": [1e-3, 0.0, 1, 1]},
        "omega_std",
        0.0,
    ),  # fmt: skip
    ("neither", {"mu": MU}, "sigma2", "neither"),
    ("no mu", {"sigma2": S2}, "mu", None),
    ("decreasing mu", {"mu": MU[::-1], "sigma2": S2}, "mu", 0.8),
    ("positive", {"mu": MU, "sigma2": [-4.0, -2.8, 0.5, -1.3]}, "sigma2", 0.5),
    (
        "std with omega",
        {"mu": MU, "omega": [2.0, 1.7, 1.3, 1.1], "sigma2_std": [1e-3] * 4},
        "sigma2_std",
        "given",
    ),  # fmt: skip
    ("text item", {"mu": MU, "sigma2": [-4.0, "x", -1.8, -1.3]}, "sigma2[1]", "x"),
    ("bool item", {"mu": [0.0, True, 0.8, 0.9], "sigma2": S2}, "mu[1]", True),
    ("unit without omega", {"mu": MU, "sigma2": S2, "omega_unit": "Hz"}, "omega_unit", "Hz"),
    (
        "unknown unit",
        {"mu": MU, "omega": [2.0, 1.7, 1.3, 1.1], "omega_unit": "deg"},
        "omega_unit",
        "deg",
    ),  # fmt: skip
    ("transition", {"mu": MU, "sigma2": S2, "transition": "fold"}, "transition", "fold"),
    ("a negative", {"mu": MU, "sigma2": S2, "a": -0.3}, "a", -0.3),
    ("a zero", {"mu": MU, "sigma2": S2, "a": 0.0}, "a", 0.0),
    ("a NaN", {"mu": MU, "sigma2": S2, "a": math.nan}, "a", "NaN"),
    ("a text", {"mu": MU, "sigma2": S2, "a": "x"}, "a", "x"),
    (
        "a against transition",
        {"mu": MU, "sigma2": S2, "transition": "saddle-node", "a": 0.3},
        "a",
        0.3,
    ),  # fmt: skip
    ("level", {"mu": MU, "sigma2": S2, "level": 1.5}, "level", 1.5),
    ("negative damping", {"mu": MU, "sigma2": S2, "damping": -1.0}, "damping", -1.0),
    ("unknown field", {"mu": MU, "sigma2": S2, "mu_unit": "deg"}, "mu_unit", "deg"),
]


@pytest.mark.anyio
@pytest.mark.parametrize("name, body, field, value", BAD, ids=[b[0] for b in BAD])
async def test_bad_tables_are_422_naming_the_field(asgi, name, body, field, value) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.post(
        "/v1/predictions",
        content=json.dumps(body, allow_nan=True).encode(),
        headers={"content-type": "application/json"},
    )
    assert r.status_code == 422, (name, r.text)
    assert r.headers["content-type"].startswith("application/problem+json")
    doc = r.json()
    assert doc["errors"][0]["field"] == field, (name, doc)
    if value is not None:
        assert doc["errors"][0]["value"] == value, (name, doc)


EXTREME: list[dict[str, Any]] = [
    {"mu": [0.0, 1e308, 1.7e308], "sigma2": [-3.0, -2.0, -1.0]},
    {"mu": [-1e308, 0.0, 1e308], "sigma2": [-3.0, -2.0, -1.0]},
    {"mu": [0.0, 1e-300, 2e-300], "sigma2": [-3.0, -2.0, -1.0]},
    {"mu": [0.0, 1.0, 2.0], "sigma2": [-1e308, -1e300, -1.0]},
    {"mu": [0.0, 1.0, 2.0], "sigma2": [-1e-308, -1e-310, -5e-324]},
    {"mu": [0.0, 1.0, 2.0], "sigma2": [-3.0, -3.0, -3.0]},
    {"mu": [0.0, 1.0, 2.0], "omega": [1e200, 1e150, 1e100]},
    {"mu": [0.0, 1.0, 2.0], "omega": [1e-200, 1e-250, 1e-300], "omega_unit": "MHz"},
    {"mu": [0.0, 1.0, 2.0], "sigma2": [-3.0, -2.0, -1.0], "sigma2_std": [5e-324] * 3},
    {"mu": [0.0, 1.0, 2.0], "sigma2": [-3.0, -2.0, -1.0], "damping": 1e308},
    {"mu": MU, "sigma2": S2, "w_static": [1e308, -1e308, 1e308, 0.0], "w_static_std": 5e-324},
    {"mu": MU, "sigma2": S2, "level": 1e-300},
    {"mu": MU, "sigma2": S2, "level": 1.0 - 1e-16},
]


@pytest.mark.anyio
@pytest.mark.parametrize("body", EXTREME)
async def test_extreme_tables_are_answered_never_5xx(asgi, body) -> None:  # noqa: ANN001
    """Values at the ends of the float range: a document, or a 422 naming a field."""
    _, client = asgi
    r = await client.post("/v1/predictions", json=body)
    assert r.status_code in (200, 422), r.text
    if r.status_code == 422:
        assert r.json()["errors"][0]["field"]


@pytest.mark.anyio
@pytest.mark.parametrize(
    "content", [b"", b"not json", b"[1, 2]", b'{"mu": [0, 1, 2], "sigma2": [-3, -2, -1]', b"null"]
)
async def test_bodies_that_are_no_table_are_422_on_the_body(asgi, content: bytes) -> None:  # noqa: ANN001
    _, client = asgi
    r = await client.post(
        "/v1/predictions", content=content, headers={"content-type": "application/json"}
    )
    assert r.status_code == 422, r.text
    assert r.json()["errors"][0]["field"] == "body"


@pytest.mark.anyio
async def test_too_many_points_are_refused_naming_the_column(asgi) -> None:  # noqa: ANN001
    """One column over ``max_prediction_points``: 422 naming it and its length, before any
    work; a body holding more values than every column could: 413 as it arrives."""
    _, client = asgi
    n = Settings().max_prediction_points + 1
    mu = np.linspace(0.0, 0.9, n)
    body = {"mu": mu.tolist(), "sigma2": (-4.0 * np.sqrt(1.0 - mu)).tolist()}
    r = await client.post("/v1/predictions", json=body)
    assert r.status_code == 422, r.text
    err = r.json()["errors"][0]
    assert (err["field"], err["value"]) == ("mu", n)
    assert "SNAPWARN_MAX_PREDICTION_POINTS" in r.json()["detail"]
    r = await client.post("/v1/predictions", json={"mu": [0.0] * (8 * n), "sigma2": [-1.0]})
    assert r.status_code == 413, r.text
    assert r.json()["errors"][0]["field"] == "body"


@pytest.mark.anyio
async def test_the_limit_is_a_setting(new_db) -> None:  # noqa: ANN001
    app = create_app(test_settings(new_db("pred-limit"), executor="thread", warm_pool=False,
                                   run_jobs=False, max_prediction_points=5))  # fmt: skip
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://asgi") as client:
            ok = {"mu": MU, "sigma2": S2}
            assert (await client.post("/v1/predictions", json=ok)).status_code == 200
            six = {"mu": [*MU, 0.95, 0.97], "sigma2": [*S2, -0.9, -0.7]}
            r = await client.post("/v1/predictions", json=six)
            assert r.status_code == 422 and r.json()["errors"][0]["value"] == 6


@pytest.mark.anyio
async def test_keys_are_required_as_on_every_route(new_db) -> None:  # noqa: ANN001
    app = create_app(test_settings(new_db("pred-auth"), executor="thread", warm_pool=False,
                                   run_jobs=False, auth="on", api_key="s3cret"))  # fmt: skip
    async with app.router.lifespan_context(app):
        transport = httpx2.ASGITransport(app=app)
        async with httpx2.AsyncClient(transport=transport, base_url="http://asgi") as client:
            body = {"mu": MU, "sigma2": S2}
            r = await client.post("/v1/predictions", json=body)
            assert r.status_code == 401 and r.json()["errors"][0]["field"] == "authorization"
            r = await client.post(
                "/v1/predictions", json=body, headers={"authorization": "Bearer s3cret"}
            )
            assert r.status_code == 200, r.text


def test_sdk_errors_are_typed_and_name_the_field(live_server) -> None:  # noqa: ANN001
    from service.client import Client, InvalidInput

    with Client(live_server.url) as sdk, pytest.raises(InvalidInput) as e:
        sdk.predict([0.0, 0.5, math.nan], [-3.0, -2.0, -1.0])
    assert e.value.status == 422
    assert "mu[2]" in str(e.value)


def test_the_route_is_in_the_openapi_document() -> None:
    from service.api import openapi_document

    doc = openapi_document()
    op = doc["paths"]["/v1/predictions"]["post"]
    assert op["requestBody"]["content"]["application/json"]["schema"] == {
        "$ref": "#/components/schemas/PredictionRequest"
    }
    assert op["responses"]["200"]["content"]["application/json"]["schema"] == {
        "$ref": "#/components/schemas/Prediction"
    }
    assert {"401", "413", "422"} <= set(op["responses"])
    req = doc["components"]["schemas"]["PredictionRequest"]
    assert {"mu", "sigma2", "omega", "omega_unit", "damping", "transition", "a"} <= set(
        req["properties"]
    )
