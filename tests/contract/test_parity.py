"""One typed contract: the numerics' result dataclasses and the wire models agree field by field,
and converting real results gives strict JSON that reads back as the same models."""

from __future__ import annotations

import json
import math
import typing
from dataclasses import dataclass, fields

import numpy as np
import pytest

from service import convert
from service.schemas import analysis as wire


def test_every_result_field_has_its_wire_field() -> None:
    assert convert.parity_problems() == []


@dataclass(frozen=True)
class _GrownMode:  # a Mode the numerics extended without telling the wire
    omega: float
    frequency: float
    damping: float
    sigma2: float
    amplitude: float
    phase: float
    omega_std: float
    damping_std: float
    sigma2_std: float
    amplitude_std: float
    regime: str
    real_poles: tuple[float, float] | None
    real_amplitudes: tuple[float, float] | None
    snr_db: float
    combination: str | None
    kind: str
    quality_factor: float


def test_a_numerics_field_change_is_caught(monkeypatch) -> None:  # noqa: ANN001
    monkeypatch.setitem(convert.PARITY, f"{__name__}:_GrownMode", (wire.Mode, frozenset(),
                                                                     frozenset()))  # fmt: skip
    problems = convert.parity_problems()
    assert problems == [f"{__name__}:_GrownMode.quality_factor has no field in Mode (add it, "
                        "or list it)"]  # fmt: skip


def test_the_method_names_are_the_detectors() -> None:
    from service.analysis.detect import METHODS
    from service.schemas import DetectionRequest

    allowed = typing.get_args(DetectionRequest.model_fields["method"].annotation)
    assert set(allowed) == set(METHODS)


def _strict_roundtrip(model: wire.BaseModel) -> dict:
    doc = model.model_dump(mode="json")
    text = json.dumps(doc, allow_nan=False)  # strict JSON: no NaN, no Infinity
    assert type(model).model_validate_json(text) == model
    return doc


def test_real_results_convert_to_strict_json() -> None:
    from service.analysis.detect import detect
    from service.analysis.pipeline import sweep_from_signals
    from service.analysis.predict import predict

    dt = 1e-3
    t = dt * np.arange(3000)
    records = []
    for k, mu in enumerate(np.linspace(0.0, 1.6, 7)):
        omega = 30.0 * math.sqrt(2.0 - mu)
        noise = np.random.default_rng(k).normal(0.0, 1e-5, t.size)
        records.append((0.1 + 1e-2 * np.exp(-0.3 * t) * np.cos(omega * t) + noise, dt, mu))
    det = detect(records[0][0], dt=dt)
    doc = _strict_roundtrip(convert.detection(det))
    # every field, in order, then the record's units (from its reader: none for arrays)
    assert [f.name for f in fields(det)] + ["time_unit", "value_unit"] == list(doc)
    assert doc["time_unit"] is None and doc["value_unit"] is None
    assert doc["fundamental"] == {**doc["modes"][det.fundamental.index],
                                  "index": det.fundamental.index}  # fmt: skip
    silent = convert.detection(detect(np.zeros(300), dt=dt))  # no mode: NaN -> None
    assert _strict_roundtrip(silent)["fundamental"] is None
    res = sweep_from_signals(records, names=[f"r{k}" for k in range(7)])
    doc = _strict_roundtrip(convert.sweep_result(res))
    assert doc["prediction"]["mu_star"] == pytest.approx(2.0, abs=1e-3)
    assert [d["control"] for d in doc["detections"]] == [r[2] for r in records]
    mu = np.array([m.mu for m in res.measurements])
    s2 = np.array([m.sigma2 for m in res.measurements])
    pred = predict(mu, s2, transition="saddle-node")
    p = _strict_roundtrip(convert.prediction(pred))
    assert p["transition"] == "saddle-node" and p["alarm"]["level"] in typing.get_args(
        wire.AlarmLevel
    )
    assert convert.sweep_document(doc) == convert.sweep_result(res)  # stored -> read back


def test_older_stored_documents_still_read() -> None:
    """A sweep stored by an earlier version (a flat document: mu* at the top level, alarms
    without a level) reads as the typed document, with the alarm rule filling the level."""
    old = {
        "actuation": "asymmetric", "model": "euler-beam", "transition": "saddle-node",
        "a": 0.25, "mu_star": 2.0, "mu_star_interval": [1.99, 2.01], "mu_star_std": 0.005,
        "probabilities": {"saddle-node": 1.0}, "n_measurements": 2, "stopped": "budget",
        "measurements": [{"mu": 0.0, "omega": 1.0, "sigma2": -1.0, "regime": "underdamped",
                          "flags": []}],
        "alarm": [{"mu": 1.9, "t_ratio": 12.0, "mu_star": 2.0, "mu_star_interval": [1.99, 2.01],
                   "distance_in_half_widths": 10.0}],
        "flags": [], "classification": {"transition": "saddle-node", "a": 0.25},
    }  # fmt: skip
    doc = convert.sweep_document(old)
    assert doc.prediction is not None and doc.prediction.mu_star == 2.0
    # the current scale, without the lab's step, counts the gap in widths: 0.09 / 0.02 = 4.5
    assert doc.alarm[0].level == "clear" and doc.alarm[0].distance == pytest.approx(10.0)
    assert doc.alarm[0].widths_left == pytest.approx(4.5) and doc.alarm[0].rank == 1
    assert doc.prediction.classification.transition == "saddle-node"


def test_one_uniform_sampling_tolerance_for_cli_and_api(monkeypatch) -> None:  # noqa: ANN001
    from service import recordings
    from service.api import Settings

    monkeypatch.delenv(recordings.UNIFORM_RTOL_ENV, raising=False)
    assert Settings().uniform_rtol == recordings.uniform_rtol_from_env()
    assert recordings.uniform_rtol_from_env() == recordings.DEFAULT_UNIFORM_RTOL
    monkeypatch.setenv(recordings.UNIFORM_RTOL_ENV, "2.5e-7")
    assert Settings().uniform_rtol == recordings.uniform_rtol_from_env() == 2.5e-7


def test_the_fundamental_is_a_mode_and_its_index() -> None:
    """On the wire the fundamental repeats its mode's fields (``det.fundamental.sigma2``)."""
    from service.analysis.detect import Fundamental, Mode

    assert {f.name for f in fields(Fundamental)} == {"mode", "index"}
    assert set(wire.Fundamental.model_fields) == set(wire.Mode.model_fields) | {"index"}
    assert set(wire.Mode.model_fields) == {f.name for f in fields(Mode)}
