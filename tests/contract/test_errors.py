"""Errors as data: the field of a 422 is the parameter the numerics name, never a word of the
message (the older door reported a bad method and a bad dt as 'w', "no fundamental" as 'no')."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _contract_helpers import run_cli

from service.analysis.errors import ParameterError
from service.api.problems import ApiProblem, as_problems, problem_from
from service.recordings import RecordingError, RecordingTooLarge, UnsupportedFormat

pytestmark = pytest.mark.anyio


def _ringdown(n: int = 2000, dt: float = 0.01) -> np.ndarray:
    t = dt * np.arange(n)
    return np.exp(-0.05 * t) * np.cos(8.0 * t) + 1e-4 * np.random.default_rng(0).normal(size=n)


def _problem(call) -> ApiProblem:  # noqa: ANN001
    with pytest.raises(ApiProblem) as e, as_problems("w"):
        call()
    return e.value


def test_detect_errors_carry_their_parameter() -> None:
    from service.analysis.detect import detect

    w = _ringdown()
    p = _problem(lambda: detect(w, dt=0.01, method="bogus"))
    assert (p.status, p.errors[0]["field"], p.errors[0]["value"]) == (422, "method", "bogus")
    for bad in (-1.0, 0.0, math.nan):
        p = _problem(lambda bad=bad: detect(w, dt=bad))
        assert p.status == 422 and p.errors[0]["field"] == "dt", p.errors


def test_no_fundamental_is_named_by_the_record_not_by_a_word() -> None:
    from service.analysis.detect import detect
    from service.analysis.measurement import measurement_from_detection

    det = detect(np.zeros(500), dt=0.01)  # nothing to find
    assert det.fundamental is None
    p = _problem(lambda: measurement_from_detection(1.25, det, 5.0, 0.01))
    assert p.errors[0]["field"] == "record" and p.errors[0]["value"] == 1.25
    assert "no fundamental" in p.detail


def test_pipeline_and_simulator_errors_carry_their_parameter() -> None:
    import sim
    from service.analysis.pipeline import sweep_from_signals

    w = _ringdown()
    p = _problem(lambda: sweep_from_signals([(w, 0.01, 0.0), (w, 0.01, 1.0)]))
    assert p.errors[0]["field"] == "records" and p.errors[0]["value"] == 2
    p = _problem(lambda: sim.Scene(probe=2.0))  # SceneError is a sim ParameterError
    assert p.errors[0]["field"] == "probe"


def test_the_mapping_of_every_error_class() -> None:
    cases = [
        (RecordingError("t[3]", 0.5, "is wrong"), 422, "t[3]"),
        (UnsupportedFormat("format", "xlsx", "is unknown"), 415, "format"),
        (RecordingTooLarge("w", 10**9, "is too long"), 413, "w"),
        (ParameterError("dt", -1.0, "dt must be > 0"), 422, "dt"),
    ]
    from sim.errors import ParameterError as SimParameterError
    from sim.errors import SimulationError

    cases += [
        (SimParameterError("elements", 10**9, "too many"), 422, "elements"),
        (SimulationError("mu", 2.5, "past the fold"), 422, "mu"),
    ]
    for exc, status, field in cases:
        p = problem_from(exc)
        assert p is not None and p.status == status and p.errors[0]["field"] == field
        assert p.errors[0]["value"] == exc.value and p.detail == str(exc)
    assert problem_from(ValueError("no field"), "measurements").errors[0]["field"] == "measurements"
    assert problem_from(ValueError("no field")) is None  # never guessed from the text
    assert problem_from(KeyError("x"), "w") is None  # not an input error: a 500, logged


async def test_api_fields(api) -> None:  # noqa: ANN001
    w = _ringdown().tolist()
    cases = [
        ({"w": w, "dt": 0.01, "method": "bogus"}, "method"),
        ({"w": w, "dt": -1.0}, "dt"),
        ({"w": w, "dt": 0.01, "t": list(range(len(w)))}, "dt"),
        ({"w": w[:1], "dt": 0.01}, "w"),
        ({"w": [*w[:5], True], "dt": 0.01}, "w[5]"),
    ]
    for doc, field in cases:
        r = await api.post("/v1/detections", json=doc)
        assert r.status_code == 422, (field, r.text)
        assert r.json()["errors"][0]["field"] == field, r.json()


def test_cli_json_errors_are_problem_documents(tmp_path) -> None:  # noqa: ANN001
    rc, doc, err = run_cli("detect", str(tmp_path / "missing.csv"), "--json")
    assert rc == 2 and doc["status"] == 422 and doc["field"] == "file"
    assert set(doc) >= {"type", "title", "status", "detail", "field", "value"}
    assert err.startswith("snapwarn: error:")
    rc, doc, _ = run_cli("detect", str(tmp_path / "x.xlsx"), "--json")
    (tmp_path / "x.xlsx").write_bytes(b"PK")
    rc, doc, _ = run_cli("detect", str(tmp_path / "x.xlsx"), "--json")
    assert rc == 2 and doc["status"] == 415 and doc["field"] == "file"
    rc, doc, _ = run_cli("warn", "--actuation", "sideways", "--json")
    assert rc == 2 and doc["status"] == 400 and "sideways" in doc["detail"]
    rc, doc, _ = run_cli("warn", "--actuation", "symmetric", "--max-measurements", "2", "--json")
    assert rc == 2 and doc["field"] == "--max-measurements" and doc["value"] == 2
    sweep = tmp_path / "sweep.csv"
    sweep.write_text("mu,sigma2\n0,-1\n0.1,-0.9\n")
    rc, doc, _ = run_cli("predict", str(sweep), "--json")
    assert rc == 2 and doc["status"] == 422 and doc["field"] in ("mu", "SWEEP"), doc


def test_cli_json_internal_errors_are_one_document_too(monkeypatch) -> None:  # noqa: ANN001
    import service.analysis.detect as detect_module

    def broken(*a, **k):  # noqa: ANN002,ANN003,ANN202
        raise RuntimeError("boom")

    monkeypatch.setattr(detect_module, "detect", broken)
    t = 0.01 * np.arange(100)
    import tempfile

    with tempfile.NamedTemporaryFile("w", suffix=".csv", delete=False) as fh:
        fh.write("t,w\n" + "".join(f"{a!r},{math.cos(a)!r}\n" for a in t.tolist()))
    rc, doc, err = run_cli("detect", fh.name, "--json")
    assert rc == 1 and doc["status"] == 500 and doc["title"] == "Internal error"
    assert "RuntimeError: boom" in doc["detail"] and err.count("\n") == 1
    with pytest.raises(RuntimeError):  # without --json people get the traceback
        run_cli("detect", fh.name)
