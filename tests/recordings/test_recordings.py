"""The one reader of lab recordings (service.recordings), on files as labs write them.

Every case is a file written the way a logger or a script would (rounded timestamps, other
units, other layouts); the expected step and time origin come from the generating grid, an
independent reference, never from the reader.
"""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from scipy.io import savemat, wavfile

from service import recordings as R
from service.recordings import RecordingError, RecordingTooLarge, UnsupportedFormat

DT = 1.0 / 3000.0  # not a short decimal: every written timestamp is rounded
N = 4000


def _grid(n: int = N, dt: float = DT, t0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    t = t0 + dt * np.arange(n)
    w = 0.3 + 1e-2 * np.exp(-0.5 * t) * np.cos(44.0 * t)
    return t, w


def _csv(header: str, t: np.ndarray, w: np.ndarray, tfmt: str, sep: str = ",") -> bytes:
    lines = [header] + [f"{tfmt % a}{sep}{b!r}" for a, b in zip(t.tolist(), w.tolist())]
    return ("\n".join(lines) + "\n").encode()


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()


# --- rounded timestamps are not irregular sampling ------------------------------------------
@pytest.mark.parametrize(
    "tfmt, flagged, rel",
    [
        ("%.17g", False, 1e-15),  # exact float64 text
        ("%.10g", False, 1e-9),  # a logger's 10 significant digits: within the tolerance
        ("%.9g", False, 1e-8),
        ("%.6g", True, 1e-8),  # 6 significant digits: steps jitter by 2 % of a step
        ("%.6f", True, 1e-8),  # fixed decimals
        ("%.4f", True, 1e-6),  # 0.1 ms resolution on a 0.33 ms step
    ],
)
def test_rounded_timestamps_give_the_least_squares_step(tfmt, flagged, rel) -> None:
    t, w = _grid(t0=0.25)
    rec = R.read_bytes(_csv("time_s,accel_mV", t, w, tfmt), "csv")
    assert rec.dt == pytest.approx(DT, rel=rel)
    assert rec.t0 == pytest.approx(0.25, abs=DT * 1e-3)
    assert rec.unit == "s" and rec.value_unit == "mV"
    np.testing.assert_array_equal(rec.w, w)  # the time column is never taken for the signal
    codes = [f.code for f in rec.flags]
    assert codes == (["rounded_timestamps"] if flagged else [])
    if flagged:
        assert "least-squares" in rec.flags[0].message


def test_rounding_is_judged_per_written_digit_not_per_step() -> None:
    """%.6g on a longer record: the written resolution grows with t (1e-6 then 1e-5)."""
    t, w = _grid(n=20_000, dt=1e-4 / 3)
    rec = R.read_bytes(_csv("t,w", t + 0.5, w, "%.6g"), "csv")
    assert rec.dt == pytest.approx(1e-4 / 3, rel=1e-7)
    assert rec.flags[0].code == "rounded_timestamps"


def test_binary_times_rounded_to_decimals_are_accepted_too() -> None:
    t, w = _grid()
    rec = R.read_bytes(_npy(np.column_stack([np.round(t, 6), w])), "npy")
    assert rec.dt == pytest.approx(DT, rel=1e-8)
    assert rec.flags[0].code == "rounded_timestamps"


def test_the_tolerance_is_one_setting(monkeypatch) -> None:  # noqa: ANN001
    t, w = _grid()
    data = _csv("t,w", t, w, "%.9g")
    assert R.read_bytes(data, "csv").flags == ()  # %.9g jitter (4e-6 of a step) < 1e-3
    monkeypatch.setenv(R.UNIFORM_RTOL_ENV, "1e-9")
    rec = R.read_bytes(data, "csv")  # below the jitter: now the rounding must explain it
    assert [f.code for f in rec.flags] == ["rounded_timestamps"]
    assert rec.dt == pytest.approx(DT, rel=1e-9)
    monkeypatch.setenv(R.UNIFORM_RTOL_ENV, "zero")
    with pytest.raises(RecordingError) as e:
        R.read_bytes(data, "csv")
    assert e.value.field == R.UNIFORM_RTOL_ENV


# --- truly irregular sampling ---------------------------------------------------------------
def test_a_dropped_sample_is_an_error_naming_the_worst_step() -> None:
    t, w = _grid()
    t, w = np.delete(t, 1000), np.delete(w, 1000)
    data = _csv("t [ms],w [mm]", 1e3 * t, w, "%.9g")
    with pytest.raises(RecordingError) as e:
        R.read_bytes(data, "csv")
    assert e.value.field == "t[1000]"
    assert e.value.value == pytest.approx(1e3 * t[1000], rel=1e-8)
    assert "resample" in str(e.value) and R.UNIFORM_RTOL_ENV in str(e.value)
    rec = R.read_bytes(data, "csv", resample=True)
    assert [f.code for f in rec.flags] == ["resampled"] and rec.t is None
    assert rec.dt == pytest.approx(1e3 * DT, rel=1e-6) and rec.unit == "ms"
    assert rec.n == N  # the grid spans the record: the missing sample is interpolated
    # against the unrounded times: the rounding of the written times (5e-7 ms) is all that differs
    np.testing.assert_allclose(rec.w, np.interp(rec.time(), 1e3 * t, w), rtol=0, atol=1e-9)


def test_a_jittering_clock_is_not_rounding() -> None:
    t, w = _grid()
    jitter = np.random.default_rng(3).uniform(-0.05, 0.05, N) * DT  # exact text: no rounding
    with pytest.raises(RecordingError) as e:
        R.read_bytes(_csv("t,w", t + jitter, w, "%.17g"), "csv")
    assert e.value.field.startswith("t[")


def test_rounding_as_coarse_as_the_step_excuses_nothing() -> None:
    """Integer-millisecond timestamps of a 1.5 ms step: the rounding could hide a lost
    sample, so the steps 1 ms and 2 ms are refused, not averaged."""
    t = 1.5 * np.arange(200)
    with pytest.raises(RecordingError) as e:
        R.read_bytes(_csv("t [ms],w", np.round(t), np.cos(t), "%.0f"), "csv")
    assert "too coarsely" in str(e.value) and e.value.field.startswith("t[")


def test_time_must_increase() -> None:
    with pytest.raises(RecordingError) as e:
        R.from_arrays([1.0, 2.0, 3.0], t=[0.0, 0.1, 0.1])
    assert e.value.field == "t[2]" and e.value.value == 0.1


# --- --dt: supplies a missing step, conflicts with a present one -----------------------------
def test_dt_supplies_the_step_of_a_one_dimensional_npy() -> None:
    _, w = _grid()
    with pytest.raises(RecordingError) as e:
        R.read_bytes(_npy(w), "npy")
    assert e.value.field == "dt" and "no sample times" in str(e.value)
    rec = R.read_bytes(_npy(w), "npy", dt=DT)
    assert rec.dt == DT and rec.t is None and rec.t0 == 0.0


def test_dt_supplies_the_step_of_a_one_column_csv() -> None:
    _, w = _grid(n=50)
    data = ("accel_mV\n" + "\n".join(map(repr, w.tolist())) + "\n").encode()
    rec = R.read_bytes(data, "csv", dt=0.5)
    assert rec.dt == 0.5 and rec.value_unit == "mV"
    np.testing.assert_array_equal(rec.w, w)


@pytest.mark.parametrize("layout", ["csv", "npy2d", "npz", "mat", "wav"])
def test_dt_conflicts_loudly_with_a_file_that_has_its_own_times(layout) -> None:  # noqa: ANN001
    t, w = _grid(n=100)
    data = {
        "csv": lambda: _csv("time_s,accel_mV", t, w, "%.17g"),
        "npy2d": lambda: _npy(np.column_stack([t, w])),
        "npz": lambda: _npz(t=t, w=w),
        "mat": lambda: _mat(w=w, dt=DT),
        "wav": lambda: _wav(3000, (w * 1e4).astype(np.int16)),
    }[layout]()
    fmt = "npy" if layout == "npy2d" else layout
    R.read_bytes(data, fmt)  # readable as it is
    with pytest.raises(RecordingError) as e:
        R.read_bytes(data, fmt, dt=0.001)
    assert e.value.field == "dt" and e.value.value == 0.001
    assert "must not be given" in str(e.value)


# --- headers and layouts --------------------------------------------------------------------
@pytest.mark.parametrize(
    "header, t_unit, w_unit",
    [
        ("t [ms], w [mm]", "ms", "mm"),
        ("time (s);deflection (um)", "s", "um"),
        ("Time_s\taccel_mV", "s", "mV"),
        ("timestamp,signal", None, None),
        ("t,x,temperature", None, None),  # two other columns: 'x' is a signal's name
    ],
)
def test_headers_as_labs_write_them(header, t_unit, w_unit) -> None:  # noqa: ANN001
    sep = ";" if ";" in header else ("\t" if "\t" in header else ",")
    t, w = _grid(n=200)
    rows = [header] + [
        sep.join([repr(a), repr(b)] + (["21.5"] if header.count(sep) == 2 else []))
        for a, b in zip(t.tolist(), w.tolist())
    ]
    rec = R.read_bytes(("\n".join(rows) + "\n").encode(), "csv")
    assert (rec.unit, rec.value_unit) == (t_unit, w_unit)
    assert rec.dt == pytest.approx(DT, rel=1e-12)
    np.testing.assert_array_equal(rec.w, w)


@pytest.mark.parametrize(
    "header, listed",
    [
        ("foo,bar", "['foo', 'bar']"),  # no time column recognised
        ("t,ch1,ch2", "['ch1', 'ch2']"),  # which of two channels?
        ("time,t,w", "['time', 't']"),  # two time columns
    ],
)
def test_an_unrecognised_header_lists_the_columns_never_guesses(header, listed) -> None:  # noqa: ANN001
    body = "\n".join(",".join(["0.1"] * header.count(",")) + f",{k}" for k in range(5))
    data = f"{header}\n{body}\n".encode()
    with pytest.raises(RecordingError) as e:
        R.read_bytes(data, "csv")
    assert e.value.field == "file" and listed in str(e.value)


def test_named_columns_resolve_what_the_header_does_not() -> None:
    t, w = _grid(n=100)
    rows = ["t,ch1,ch2"] + [f"{a!r},{-b!r},{b!r}" for a, b in zip(t.tolist(), w.tolist())]
    rec = R.read_bytes(("\n".join(rows) + "\n").encode(), "csv", column="ch2")
    np.testing.assert_array_equal(rec.w, w)
    with pytest.raises(RecordingError) as e:
        R.read_bytes(("\n".join(rows) + "\n").encode(), "csv", column="ch3")
    assert e.value.field == "column" and "['t', 'ch1', 'ch2']" in str(e.value)


def _npz(**arrays: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _mat(**arrays: object) -> bytes:
    buf = io.BytesIO()
    savemat(buf, arrays)
    return buf.getvalue()


def _wav(rate: int, a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    wavfile.write(buf, rate, a)
    return buf.getvalue()


def test_npz_mat_wav_layouts() -> None:
    t, w = _grid(n=300)
    for rec in (
        R.read_bytes(_npz(t=t, w=w), "npz"),
        R.read_bytes(_npz(signal=w, dt=np.float64(DT)), "npz"),
        R.read_bytes(_mat(w=w, t=t), "mat"),
        R.read_bytes(_mat(w=w.reshape(-1, 1), dt=DT), "mat"),  # MATLAB's column vector
        R.read_bytes(_npy(np.vstack([t, w])), "npy"),  # two rows
    ):
        assert rec.dt == pytest.approx(DT, rel=1e-12)
        np.testing.assert_array_equal(rec.w, w)
    stereo = np.stack([np.arange(100), -np.arange(100)], axis=1).astype(np.int16)
    rec = R.read_bytes(_wav(3000, stereo), "wav", channel=1)
    assert rec.dt == pytest.approx(1 / 3000) and rec.w[5] == -5.0 and rec.unit == "s"
    for bad in (2, math.inf, 0.5):
        with pytest.raises(RecordingError) as e:
            R.read_bytes(_wav(3000, stereo), "wav", channel=bad)
        assert e.value.field == "channel"


def test_bad_inputs_name_the_field() -> None:
    with pytest.raises(UnsupportedFormat):
        R.guess_format("run.xlsx")
    with pytest.raises(RecordingTooLarge):
        R.from_arrays(np.zeros(11), dt=1.0, max_samples=10)
    with pytest.raises(RecordingError) as e:
        R.from_arrays([True, False, True], dt=1.0)
    assert e.value.field == "w" and "booleans" in str(e.value)
    with pytest.raises(RecordingError) as e:
        R.from_arrays([1.0, math.nan, 2.0], dt=1.0)
    assert e.value.field == "w[1]"
    with pytest.raises(RecordingError) as e:
        R.read_bytes(_mat(w={"a": 1}), "mat")
    assert e.value.field == "w"
    for bad in (0.0, 1e-300, 1e300):  # a step whose square under/overflows: no finite rate
        with pytest.raises(RecordingError) as e:
            R.from_arrays([1.0, 2.0], dt=bad)
        assert e.value.field == "dt"
    for fine in (1e-150, 1e150):
        assert R.from_arrays([1.0, 2.0], dt=fine).dt == fine
    assert isinstance(e.value, ValueError) and e.value.parameter == "dt"


def test_units_do_not_change_the_physics() -> None:
    """The same record in seconds and in milliseconds: omega scales by 1000, nothing else."""
    from service.analysis.detect import detect

    t, w = _grid()
    s = R.read_bytes(_csv("time_s,w", t, w, "%.9g"), "csv")
    ms = R.read_bytes(_csv("t [ms],w", 1e3 * t, w, "%.9g"), "csv")
    a, b = detect(s.w, dt=s.dt), detect(ms.w, dt=ms.dt)
    assert a.fundamental.omega == pytest.approx(44.0, rel=1e-6)
    assert b.fundamental.omega * 1e3 == pytest.approx(a.fundamental.omega, rel=1e-8)


def test_decimal_commas_of_a_spreadsheet_export() -> None:
    t, w = _grid(n=100)
    rows = ["Zeit [s];Weg [mm]"] + [f"{a:.9g};{b:.9g}".replace(".", ",")
                                    for a, b in zip(t.tolist(), w.tolist())]  # fmt: skip
    rec = R.read_bytes(("\n".join(rows) + "\n").encode(), "csv", time_column="Zeit")
    assert rec.dt == pytest.approx(DT, rel=1e-8) and (rec.unit, rec.value_unit) == ("s", "mm")
    np.testing.assert_allclose(rec.w, w, rtol=1e-8)
