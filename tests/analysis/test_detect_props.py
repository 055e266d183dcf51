"""Property tests: never a NaN or an infinity in a detection without a flag explaining it."""

from __future__ import annotations

import json
import math
from dataclasses import fields

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from service import convert
from service.analysis.detect import Detection, detect


def _floats(obj) -> list[float]:
    out = []
    for f in fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, float):
            out.append(v)
        elif isinstance(v, tuple) and v and all(isinstance(x, float) for x in v):
            out.extend(v)
    return out


def _check(det: Detection) -> None:
    values = _floats(det)
    for m in det.modes:
        values += _floats(m)
    if det.fundamental is not None:
        values += _floats(det.fundamental)
    if not all(math.isfinite(v) for v in values):
        assert det.flags, f"non-finite value without a flag: {det}"
    # the document is always strict JSON (non-finite -> None)
    json.dumps(convert.detection(det).model_dump(mode="json"), allow_nan=False)
    # NaN only where a flag says why (a lab record whose baseline moves)
    assert math.isfinite(det.static_level) or "baseline_drift" in det.flag_codes
    for m in det.modes:
        assert math.isfinite(m.omega) and math.isfinite(m.sigma2)
        assert m.regime in ("underdamped", "overdamped")
    if det.fundamental is None:
        assert "no_mode" in det.flag_codes
    else:
        assert det.fundamental.regime in ("underdamped", "overdamped")


records = st.fixed_dictionaries(
    {
        "n": st.integers(16, 3000),
        "kind": st.sampled_from(["noise", "constant", "modes", "modes+noise", "step", "spike"]),
        "log_scale": st.floats(-12, 12),
        "offset": st.floats(-1e3, 1e3),
        "n_modes": st.integers(1, 4),
        "seed": st.integers(0, 2**31 - 1),
        "log_dt": st.floats(-6, 3),
    }
)


def _make(spec) -> np.ndarray:
    rng = np.random.default_rng(spec["seed"])
    n = spec["n"]
    scale = 10.0 ** spec["log_scale"]
    t = np.arange(n, dtype=float)
    kind = spec["kind"]
    if kind == "constant":
        x = np.zeros(n)
    elif kind == "noise":
        x = rng.standard_normal(n)
    elif kind == "step":
        x = (t > n / 2).astype(float)
    elif kind == "spike":
        x = np.zeros(n)
        x[rng.integers(0, n)] = 1.0
    else:
        x = np.zeros(n)
        for _ in range(spec["n_modes"]):
            om = rng.uniform(0.001, 3.1)
            g = 10 ** rng.uniform(-5, -0.5)
            x += rng.uniform(0.1, 1) * np.exp(-g * t) * np.cos(om * t + rng.uniform(0, 6.3))
        if kind == "modes+noise":
            x += 10 ** rng.uniform(-4, 0) * rng.standard_normal(n)
    return spec["offset"] + scale * x


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,
)
@given(records, st.sampled_from(["auto", "fft", "fft-parabolic", "esprit"]))
def test_never_nan_or_inf_without_a_flag(spec, method) -> None:
    w = _make(spec)
    dt = 10.0 ** spec["log_dt"]
    _check(detect(w, dt=dt, method=method))


@settings(max_examples=25, deadline=None, derandomize=True)
@given(records)
def test_common_damping_and_ambient_never_nan_without_a_flag(spec) -> None:
    w = _make(spec)
    dt = 10.0 ** spec["log_dt"]
    _check(detect(w, dt=dt, common_damping=True))
    _check(detect(w, dt=dt, kind="ambient"))


@settings(max_examples=30, deadline=None, derandomize=True)
@given(records, st.sampled_from(["auto", "fft", "esprit"]))
def test_flag_codes_are_documented(spec, method) -> None:
    from service.analysis.detect import FLAG_CODES

    det = detect(_make(spec), dt=10.0 ** spec["log_dt"], method=method)
    assert set(det.flag_codes) <= set(FLAG_CODES)
