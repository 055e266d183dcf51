"""Lab files the project did not write, read by the CLI (in-process) and checked against the
truth they were generated from (see ``_foreign``): a record's omega, a sweep's mu* in the
lab's own control unit; broken files give an error naming the field, never a traceback."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "contract"))
from _contract_helpers import run_cli  # noqa: E402
from _foreign import bad_records, beam_grid, lab_records, table  # noqa: E402

from service import recordings as R  # noqa: E402


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict:
    d = tmp_path_factory.mktemp("foreign")
    return {"good": lab_records(d), "bad": bad_records(d)}


@pytest.mark.parametrize("name", [
    "comments.csv", "units_row.csv", "scope.csv", "excel_unicode.txt", "legacy.csv",
    "named.npz", "logger.npz", "table.npz", "rate.npz", "daq.mat", "UPPER.CSV",
    "excel_sep.csv", "struct.mat", "epoch.npy", "savetxt.txt", "savetxt.csv", "iso.csv",
    "iso_zone.csv", "time_of_day.csv", "pretrigger.csv", "release.csv",
])  # fmt: skip
def test_a_lab_record_gives_its_true_frequency(files, name) -> None:  # noqa: ANN001
    path, omega = files["good"][name]
    rc, doc, err = run_cli("detect", str(path), "--json")
    assert rc == 0, err
    assert "Traceback" not in err
    # noise 1e-3 on a unit ringdown of 4000 samples: omega to ~1e-5; 1e-4 leaves room
    assert doc["fundamental"]["omega"] == pytest.approx(omega, rel=1e-4)
    assert len(doc["modes"]) == 1


def test_units_from_a_row_under_the_header() -> None:
    t = np.arange(5) * 1e-3
    for units, expect in (("s,mm", ("s", "mm")), ("(ms),(V)", ("ms", "V")),
                          ("[s],", ("s", None))):  # fmt: skip
        text = table(f"time,w\n{units}", [t * (1e3 if "ms" in units else 1), t], ["%g", "%g"])
        rec = R.read_bytes(text.encode(), "csv")
        assert (rec.unit, rec.value_unit) == expect
        assert rec.n == 5  # the units row is not a sample


def test_error_lines_are_the_files_own_lines(files) -> None:  # noqa: ANN001
    path, field = files["bad"]["bad_cell.csv"]
    assert path.read_text().splitlines()[10].endswith(",n/a")  # line 11 as an editor counts
    rc, doc, err = run_cli("detect", str(path), "--json")
    assert rc == 2 and doc["field"] == field and doc["value"] == "n/a"
    assert "Traceback" not in err


@pytest.mark.parametrize("name", ["rate_conflict.npz", "two_signals.npz"])
def test_ambiguous_variables_are_refused_by_name(files, name) -> None:  # noqa: ANN001
    path, field = files["bad"][name]
    rc, doc, err = run_cli("detect", str(path), "--json")
    assert rc == 2 and doc["field"] == field, doc
    assert doc["status"] == 422 and "Traceback" not in err


def test_binary_bytes_are_not_read_as_legacy_text() -> None:
    with pytest.raises(R.RecordingError) as e:
        R.read_bytes(b"t,w\n0,1\n\x00\xff\x00,2\n", "csv")
    assert e.value.field == "file"


# --- sweep tables ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fold() -> tuple:
    """The asymmetric beam (a fold) on a fixed grid of 0.05 stopping 0.01 before mu*."""
    return beam_grid("asymmetric", 0.05, 0.01)


def _predict(path: Path, *extra: str) -> dict:
    rc, doc, err = run_cli("predict", str(path), "--json", *extra)
    assert rc == 0, err
    return doc


def test_a_sweep_in_degrees_and_hertz_gives_mu_star_in_degrees(tmp_path, fold) -> None:  # noqa: ANN001
    ms, mu, s2, sd = fold
    om, om_sd = np.sqrt(-s2), sd / (2 * np.sqrt(-s2))
    plain = tmp_path / "rad.csv"
    plain.write_text(table("mu,omega,omega_std", [mu, om, om_sd], ["%.17g"] * 3))
    lab = tmp_path / "deg.csv"
    lab.write_bytes(("\ufeff# strip B, 2025-03-02\n" + table(
        "theta [deg];omega [Hz];omega_std [Hz]",
        [np.degrees(mu), om / (2 * np.pi), om_sd / (2 * np.pi)], ["%.15g"] * 3, sep=";",
    )).encode())  # fmt: skip
    rad = _predict(plain)
    deg = _predict(lab, "--control-column", "theta")
    assert rad["transition"] == deg["transition"] == "saddle-node"
    lo, hi = rad["mu_star_interval"]
    assert lo <= ms <= hi  # the truth, in radians
    assert abs(rad["mu_star"] - ms) < 1e-3
    # the same answer in the lab's unit (degrees): equivariant to the written digits
    assert deg["mu_star"] == pytest.approx(math.degrees(rad["mu_star"]), rel=1e-7)
    dlo, dhi = deg["mu_star_interval"]
    assert dlo <= math.degrees(ms) <= dhi


def test_hertz_is_read_as_cycles(tmp_path, fold) -> None:  # noqa: ANN001
    """With a damping given (1/s), omega [Hz] must be turned into rad/s, not read as rad/s."""
    ms, mu, s2, sd = fold
    om = np.sqrt(-s2)
    a, b = tmp_path / "rad.csv", tmp_path / "hz.csv"
    a.write_text(table("mu,omega", [mu, om], ["%.17g"] * 2))
    b.write_text(table("mu,omega [Hz]", [mu, om / (2 * np.pi)], ["%.17g"] * 2))
    ra, rb = _predict(a, "--damping", "0.5"), _predict(b, "--damping", "0.5")
    assert rb["mu_star"] == pytest.approx(ra["mu_star"], rel=1e-9)


@pytest.mark.parametrize(
    "text, field, value",
    [
        ("mu,omega\n0,10\n0.5,9\n1,NaN\n1.5,7\n", "file: line 4, column 'omega'", "NaN"),
        ("# run 3\nmu,omega\n0,10\n0.5,\n1,8\n", "file: line 4, column 'omega'", ""),
        ("mu;omega\n0;10\n0,5;9\n1;8;3\n", "file: line 4", "3 cells"),
        ("theta,omega\n0,10\n1,9\n", "SWEEP", None),  # no mu: the columns are listed
    ],
)
def test_a_broken_sweep_table_names_line_and_column(tmp_path, text, field, value) -> None:  # noqa: ANN001
    p = tmp_path / "s.csv"
    p.write_text(text)
    rc, doc, err = run_cli("predict", str(p), "--json")
    assert rc == 2 and doc["field"] == field, doc
    if value is not None:
        assert doc["value"] == value
    else:
        assert "['theta', 'omega']" in doc["detail"]
    assert "Traceback" not in err


def test_a_spreadsheet_sweep_with_bom_and_trailing_rows(tmp_path, fold) -> None:  # noqa: ANN001
    ms, mu, s2, sd = fold
    p = tmp_path / "excel.csv"
    body = table("mu,sigma2,sigma2_std", [mu, s2, sd], ["%.17g"] * 3)
    p.write_bytes(("\ufeff" + body + ",,\n,,\n").replace("\n", "\r\n").encode())
    doc = _predict(p)
    assert doc["transition"] == "saddle-node"
    lo, hi = doc["mu_star_interval"]
    assert lo <= ms <= hi


def test_a_saturated_sensor_is_flagged_and_a_decaying_record_is_not(tmp_path) -> None:  # noqa: ANN001
    """A clipped ringdown biased the detector (omega 38.3 for the true 44.0): the reader's
    ``clipped`` flag reaches the detection, and the detector leaves the clipped samples out of
    its fit (its own flag ``clipped``): the fundamental is right again. The same record
    unclipped, or quantised, is not flagged."""
    from _foreign import OMEGA, ringdown

    t, w = ringdown()
    clipped = tmp_path / "clipped.csv"
    clipped.write_text(table("t,w", [t, np.clip(w, -0.7, 0.7)], ["%.6f", "%.6e"]))
    rc, doc, err = run_cli("detect", str(clipped), "--json")
    assert rc == 0, err
    codes = [f["code"] for f in doc["flags"]]
    assert codes[0] == "clipped" and codes.count("clipped") == 2  # the reader's, the detector's
    assert abs(doc["fundamental"]["omega"] / OMEGA - 1) < 1e-3
    for fine in (w, np.round(w * 100) / 100, np.round(w * 3e4)):
        assert not R.from_arrays(fine, dt=1e-3).flags


def test_sweep_errors_echo_plain_numbers_and_say_the_direction() -> None:
    """The message shows the lab's number (not ``np.float64(...)``), and a sweep written from
    the top down is told how to be read."""
    from service.analysis.predict import predict

    mu = np.array([0.0, 0.5, 1.0])
    with pytest.raises(ValueError) as e:
        predict(mu, np.array([-3.0, 0.25, -1.0]))
    assert e.value.parameter == "sigma2" and "sigma2[1]=0.25" in str(e.value)
    assert "np." not in str(e.value)
    with pytest.raises(ValueError) as e:
        predict(mu[::-1], np.array([-1.0, -2.0, -3.0]))
    assert e.value.parameter == "mu" and "give -mu" in str(e.value)


def test_the_cli_takes_the_readers_options_the_api_takes(tmp_path) -> None:  # noqa: ANN001
    """A file the CLI's own error tells to 'name the format' / 'name it with column' can be
    named on the command line (the API's upload fields format, column, channel)."""
    from _foreign import OMEGA, ringdown

    t, w = ringdown()
    two = tmp_path / "two.csv"
    two.write_text(table("t,ch1,ch2", [t, -w, w], ["%.6f", "%.6e", "%.6e"]))
    rc, doc, _ = run_cli("detect", str(two), "--json")
    assert rc == 2 and "name it with column" in doc["detail"]
    rc, doc, err = run_cli("detect", str(two), "--column", "ch2", "--json")
    assert rc == 0 and doc["fundamental"]["omega"] == pytest.approx(OMEGA, rel=1e-4), err
    bare = tmp_path / "export"  # no extension
    bare.write_text(table("t,w", [t, w], ["%.6f", "%.6e"]))
    rc, doc, _ = run_cli("detect", str(bare), "--json")
    assert rc == 2 and doc["status"] == 415 and "name the format" in doc["detail"]
    rc, doc, err = run_cli("detect", str(bare), "--format", "csv", "--json")
    assert rc == 0 and doc["fundamental"]["omega"] == pytest.approx(OMEGA, rel=1e-4), err


def test_excel_sep_line_matlab_struct_and_v73(tmp_path) -> None:  # noqa: ANN001
    from _foreign import DT, mat, ringdown

    t, w = ringdown()
    text = 'sep=;\n' + table("t;w", [t, w], ["%.6f", "%.6e"], sep=";")
    rec = R.read_bytes(text.encode(), "csv")
    assert rec.dt == pytest.approx(DT, rel=1e-9) and rec.n == t.size
    sweep = R.read_table(b'"sep=;"\nmu;omega\n0;1\n1;2\n')
    assert sweep.names == ["mu", "omega"] and sweep.floats("omega").tolist() == [1.0, 2.0]
    rec = R.read_bytes(mat(run={"t": t, "w": w}), "mat")  # a MATLAB struct: run.t, run.w
    assert rec.dt == pytest.approx(DT, rel=1e-9)
    np.testing.assert_array_equal(rec.w, w)
    v73 = b"MATLAB 7.3 MAT-file, Platform: GLNXA64".ljust(512) + b"\x89HDF\r\n\x1a\n" + bytes(64)
    with pytest.raises(R.RecordingError) as e:
        R.read_bytes(v73, "mat")
    assert e.value.field == "file" and "-v7" in str(e.value)


@pytest.mark.parametrize("fs", [1e4, 1e5])
def test_epoch_times_in_binary_floats_are_uniform_to_their_rounding(tmp_path, fs) -> None:  # noqa: ANN001
    """Unix times (1.7e9 s) stored as float64 at 10-100 kHz: float64's own spacing there
    (2.4e-7 s) is a few thousandths of a step; that is not irregular sampling (was refused as
    'written too coarsely'). A dropped sample is still named."""
    n = 20000
    k = np.arange(n)
    t = 1.7e9 + k / fs
    omega = 2 * np.pi * fs / 100.0  # 100 samples a period
    w = np.exp(-fs / 4000.0 * k / fs) * np.cos(omega * k / fs)
    p = tmp_path / "epoch.npy"
    np.save(p, np.column_stack([t, w]))
    rc, doc, err = run_cli("detect", str(p), "--json")
    assert rc == 0, err
    assert doc["fundamental"]["omega"] == pytest.approx(omega, rel=1e-5)
    keep = np.ones(n, bool)
    keep[5000] = False
    with pytest.raises(R.RecordingError) as e:
        R.from_arrays(w[keep], t=t[keep])
    assert e.value.field == "t[5000]"


def test_clock_times_and_savetxt_headers() -> None:
    """A logger's clock (ISO 8601, times of day) is read as seconds from the first reading,
    rounded as written (milliseconds: a 0.5 ms quantum, so 1 ms steps are uniform); a header
    that numpy.savetxt wrote as a comment is the header, and a comment that does not name the
    columns is not."""
    rec = R.read_bytes(b"time,w\n10:00:00.000,1\n10:00:00.001,2\n10:00:00.002,3\n", "csv")
    assert rec.unit == "s" and rec.dt == pytest.approx(1e-3, rel=1e-12)
    with pytest.raises(R.RecordingError) as e:
        R.read_bytes(b"time,w\n10:00:00.000,1\n10:00:00.001,2\nsoon,3\n", "csv")
    assert e.value.field == "file: line 4, column 'time'" and e.value.value == "soon"
    with pytest.raises(R.RecordingError) as e:
        R.read_bytes(b"time,w\n2026-01-01T10:00:00.000,1\n2026-01-01T10:00:00.001Z,2\n", "csv")
    assert "time zone" in str(e.value)
    sweep = R.read_table(b"# mu,sigma2\n0,-4\n1,-3\n")
    assert sweep.names == ["mu", "sigma2"] and sweep.lines == [2, 3]
    with pytest.raises(R.RecordingError, match="no header row"):
        R.read_table(b"# my sweep of Tuesday\n0,-4\n1,-3\n")


def test_units_in_the_variables_names_of_npz_and_mat() -> None:
    """``t_ms``, ``time_s``, ``w_mm`` name their units as a CSV header does (they were read as
    the time and the signal, their units dropped: a sweep could not tell ms from s)."""
    from _foreign import mat, npz, ringdown

    t, w = ringdown()
    rec = R.read_bytes(npz(t_ms=1e3 * t, w_mm=w), "npz")
    assert (rec.unit, rec.value_unit) == ("ms", "mm") and rec.dt == pytest.approx(1.0)
    rec = R.read_bytes(mat(time_s=t, deflection_mm=w), "mat")
    assert (rec.unit, rec.value_unit) == ("s", "mm") and rec.dt == pytest.approx(1e-3)
    rec = R.read_bytes(mat(run={"t_ms": 1e3 * t, "w": w}), "mat")
    assert (rec.unit, rec.value_unit) == ("ms", None)
