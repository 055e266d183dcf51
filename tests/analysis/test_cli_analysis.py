"""The analysis CLI: detect, predict, warn — one JSON document, documented keys, clear errors."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from service.cli import main
from sim import simulate
from sim.euler_beam import bifurcation, spectrum
from sim.scene import Scene


def run_json(capsys, *argv: str) -> dict:
    assert main([*argv, "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1
    return json.loads(out)


def test_detect_on_a_simulated_csv(tmp_path, capsys) -> None:
    out = tmp_path / "s.csv"
    assert main(["simulate", "--actuation", "symmetric", "--mu", "1.5", "--snr", "40",
                 "--seed", "1", "--out", str(out)]) == 0  # fmt: skip
    capsys.readouterr()
    doc = run_json(capsys, "detect", str(out))
    assert {"modes", "fundamental", "flags"} <= set(doc)
    for m in doc["modes"]:
        assert {"omega", "frequency", "damping", "sigma2", "amplitude", "omega_std"} <= set(m)
    f = doc["fundamental"]
    assert {"omega", "sigma2", "sigma2_std", "regime"} <= set(f)
    exact = spectrum("symmetric", 1.5, "U_A", modes=1).sigma2[0]
    assert f["sigma2"] == pytest.approx(exact, rel=1e-3)
    assert f["regime"] == "underdamped"
    base = run_json(capsys, "detect", str(out), "--method", "fft")
    assert abs(base["fundamental"]["sigma2"] / exact - 1) > abs(f["sigma2"] / exact - 1)


def test_predict_from_a_sweep_table(tmp_path, capsys) -> None:
    mu_star = bifurcation("antisymmetric").mu_star
    mus = mu_star - np.geomspace(0.5, 1e-3, 10)
    path = tmp_path / "sweep.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["mu", "sigma2", "sigma2_std"])
        for m in mus:
            s2 = spectrum("antisymmetric", m, "U_A", modes=1).sigma2[0]
            w.writerow([m, s2, 1e-6 * abs(s2)])
    doc = run_json(capsys, "predict", str(path))
    assert {"transition", "a", "mu_star", "mu_star_interval", "probabilities", "flags"} <= set(doc)
    assert doc["mu_star"] == pytest.approx(mu_star, abs=1e-4)
    assert doc["a"] == pytest.approx(0.5)


def test_predict_rejects_bad_tables(tmp_path, capsys) -> None:
    p = tmp_path / "bad.csv"
    p.write_text("mu,sigma2\n0.1,-5\n0.2,abc\n0.3,-3\n")
    assert main(["predict", str(p), "--json"]) == 2
    err = capsys.readouterr().err
    assert "sigma2" in err and "bad.csv" in err
    p.write_text("mu,x\n0.1,1\n")
    assert main(["predict", str(p)]) == 2
    assert "sigma2" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("header", "field"),
    [("mu,sigma2,omega_std", "omega_std"), ("mu,omega,sigma2_std", "sigma2_std"),
     ("mu,sigma2,w_static_std", "w_static_std")],
)
def test_predict_refuses_a_std_column_without_its_column(
    tmp_path, capsys, header: str, field: str
) -> None:
    """A std column whose quantity is absent is refused naming it, as over HTTP (it was
    dropped without a word)."""
    p = tmp_path / "t.csv"
    rows = [f"{1 - x},{-x if 'sigma2,' in header else x**0.5},0.01" for x in
            np.geomspace(1, 1e-3, 10)]  # fmt: skip
    p.write_text(header + "\n" + "\n".join(rows) + "\n")
    assert main(["predict", str(p), "--json"]) == 2
    problem = json.loads(capsys.readouterr().out)  # --json: the problem document on stdout
    assert problem["field"] == field, problem


def test_detect_rejects_a_missing_file(capsys) -> None:
    assert main(["detect", "/nonexistent/rec.csv", "--json"]) == 2
    err = capsys.readouterr().err
    assert "/nonexistent/rec.csv" in err and err.count("\n") == 1


def test_warn_json_document(capsys) -> None:
    doc = run_json(capsys, "warn", "--model", "normal-form", "--actuation", "antisymmetric",
                   "--seed", "2", "--max-measurements", "10", "--no-progress")  # fmt: skip
    # the sweep document (service.schemas.SweepResult), shared with `sweep` and /v1/sweeps
    assert {"actuation", "model", "measurements", "prediction", "alarm", "stopped",
            "flags"} <= set(doc)  # fmt: skip
    p = doc["prediction"]
    assert {"transition", "a", "mu_star", "mu_star_interval", "baseline"} <= set(p)
    assert len(doc["measurements"]) <= 10 and len(doc["alarm"]) == len(doc["measurements"])
    for m in doc["measurements"]:
        assert {"mu", "omega", "sigma2", "sigma2_std", "w_static"} <= set(m)
    assert "mu_star" in p["baseline"] and doc["alarm"][-1]["level"] in (
        "insufficient", "clear", "watch", "warning", "critical")  # fmt: skip
    assert doc["alarm"][-1] == p["alarm"]  # one alarm per document


def test_simulated_record_round_trip_through_detect_keeps_static_level(tmp_path, capsys) -> None:
    sig = simulate(Scene(actuation="asymmetric", mu=1.0, kick=1e-3, snr_db=50, seed=4))
    p = tmp_path / "r.npy"
    np.save(p, np.column_stack([sig.t, sig.w]))
    doc = run_json(capsys, "detect", str(p))
    assert doc["static_level"] == pytest.approx(sig.w_static, abs=1e-5)


def test_predict_table_of_rates_with_every_column_and_damping(tmp_path, capsys) -> None:
    """omega, omega_std, w_static, w_static_std and --damping reach the predictor: the CLI's
    document is the function's (each column dropped or the damping changed changes it)."""
    from service import convert
    from service.analysis.predict import predict

    mu_star = bifurcation("asymmetric").mu_star
    mus = mu_star - np.geomspace(1.0, 1e-3, 12)
    om = np.array([np.sqrt(-spectrum("asymmetric", m, "U_A", modes=1).sigma2[0]) for m in mus])
    w = 0.1 + 0.01 * np.sqrt(mu_star - mus)
    cols = {"mu": mus, "omega": om, "omega_std": 1e-5 * om, "w_static": w,
            "w_static_std": np.full(mus.size, 1e-7)}  # fmt: skip
    path = tmp_path / "rates.csv"
    with path.open("w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(list(cols))
        for i in range(mus.size):
            wr.writerow([repr(float(cols[k][i])) for k in cols])
    doc = run_json(capsys, "predict", str(path), "--damping", "0.5")
    want = predict(mus, omega=om, omega_std=1e-5 * om, w_static=w,
                   w_static_std=np.full(mus.size, 1e-7), damping=0.5)  # fmt: skip
    assert doc == json.loads(convert.prediction(want).model_dump_json())
    other = predict(mus, omega=om, omega_std=1e-5 * om, w_static=w, damping=0.5)
    assert json.loads(convert.prediction(other).model_dump_json()) != doc


@pytest.mark.parametrize(
    ("header", "to_column"),
    [
        ("mu,freq_Hz", lambda om: om / (2 * np.pi)),  # a logger's frequency in Hz
        ("mu,f [kHz]", lambda om: om / (2 * np.pi * 1e3)),
        ("mu,frequency", lambda om: om / (2 * np.pi)),  # no unit: Hz
        ("mu,period [ms]", lambda om: 2e3 * np.pi / om),  # the paper's T, in ms
    ],
)
def test_predict_reads_a_frequency_or_a_period_as_omega(tmp_path, capsys, header, to_column) -> None:  # noqa: ANN001,E501
    """A table that gives the fundamental's frequency or period (what a lab's counter or the
    paper's T measure) predicts as the same table in omega: mu* does not depend on the time
    unit, and the rates are 2 pi f or 2 pi / T."""
    mu_star = bifurcation("asymmetric").mu_star
    mus = np.arange(0.0, mu_star - 0.01, 0.1)  # a fixed grid
    om = np.array([np.sqrt(-spectrum("asymmetric", m, "U_A", modes=1).sigma2[0]) for m in mus])
    ref = tmp_path / "omega.csv"
    rows = zip(mus.tolist(), om.tolist(), to_column(om).tolist())
    ref.write_text("mu,omega\n" + "".join(f"{m!r},{o!r}\n" for m, o, _ in rows))
    p = tmp_path / "t.csv"
    rows = zip(mus.tolist(), om.tolist(), to_column(om).tolist())
    p.write_text(header + "\n" + "".join(f"{m!r},{v!r}\n" for m, _, v in rows))
    want = run_json(capsys, "predict", str(ref))
    got = run_json(capsys, "predict", str(p))
    assert got["transition"] == want["transition"] == "saddle-node"
    # the same answer to 1e-5 of its own interval: the columns differ in their last bits
    # (2 pi f, 2 pi / T), and on these noise-free rates (the noise read from the laws' own
    # misfit) one ulp moves the interval's upper end by 4e-7 of its width (measured, kHz)
    width = want["mu_star_interval"][1] - want["mu_star_interval"][0]
    assert abs(got["mu_star"] - want["mu_star"]) < 1e-5 * width
    for a, b in zip(got["mu_star_interval"], want["mu_star_interval"], strict=True):
        assert abs(a - b) < 1e-5 * width


def test_predict_refuses_a_period_that_is_not_positive(tmp_path, capsys) -> None:
    p = tmp_path / "t.csv"
    p.write_text("mu,period\n0,1.0\n0.1,1.1\n0.2,0\n0.3,1.4\n")
    assert main(["predict", str(p), "--json"]) == 2
    problem = json.loads(capsys.readouterr().out)
    assert problem["field"] == "period[2]" and problem["value"] == 0.0, problem


def test_an_all_positive_sigma2_column_is_told_how_to_give_it(tmp_path, capsys) -> None:
    """|sigma2| written as a positive omega^2: the error says what to do."""
    p = tmp_path / "t.csv"
    p.write_text("mu,sigma2\n0,4.0\n0.1,3.0\n0.2,2.0\n0.3,1.0\n")
    assert main(["predict", str(p)]) == 2
    err = capsys.readouterr().err
    assert "every value is >= 0" in err and "give its negative" in err, err


def test_detect_line_is_the_wire_documents(tmp_path, capsys) -> None:
    """``snapwarn detect`` prints its line from the numerics (no pydantic loaded); it is the line
    the wire document gives (``--json`` path), flags of the reader and the detector included:
    a clean ring-down, an overdamped record, one with a pre-trigger and hum, one with a unit,
    and noise only (no fundamental)."""
    from service import convert
    from service.analysis.detect import detect
    from service.cli.analysis_cmds import detection_text
    from service.recordings import read_file

    rng = np.random.default_rng(11)
    t = np.arange(3000) * 1e-3
    cases = {
        "clean.csv": np.exp(-3 * t) * np.cos(50 * t),
        "over.csv": np.exp(-40 * t) - 0.5 * np.exp(-90 * t),
        "lab.csv": np.r_[np.zeros(600), np.exp(-3 * t[:2400]) * np.sin(60 * t[:2400])]
        + 0.05 * np.sin(2 * np.pi * 50 * t) + 1e-2 * rng.normal(size=3000),
        "noise.csv": 1e-3 * rng.normal(size=3000),
    }
    for name, w in cases.items():
        p = tmp_path / name
        np.savetxt(p, np.c_[t, w], delimiter=",", header="t_s,w_mm" if name == "lab.csv"
                   else "t,w", comments="")  # fmt: skip
        assert main(["detect", str(p)]) == 0
        line = capsys.readouterr().out.strip()
        rec = read_file(p)
        doc = convert.detection(detect(rec.w, dt=rec.dt), extra_flags=rec.flags,
                                time_unit=rec.unit, value_unit=rec.value_unit)  # fmt: skip
        want = detection_text(doc.fundamental, len(doc.modes), [f.code for f in doc.flags],
                              rec.unit)  # fmt: skip
        assert line == want, name
