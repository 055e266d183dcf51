"""The early-warning pipeline end to end on the Euler beam, and the lab-data sweep."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from service.analysis.alarm import next_measurement, sigma4_bound
from service.analysis.pipeline import sweep_from_signals, warn
from service.cli import main
from sim import simulate
from sim.euler_beam import bifurcation, spectrum
from sim.scene import Scene


def test_sigma4_bound_is_conservative_on_the_beam() -> None:
    """The model-free safety bound never lies beyond mu* once the slowdown has begun."""

    for act in ("asymmetric", "symmetric", "antisymmetric"):
        mu_star = bifurcation(act).mu_star
        mus = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.7, 1.75, 1.77])
        mus = mus[mus < mu_star]
        y = np.array([-spectrum(act, m, "U_A", modes=1).sigma2[0] for m in mus])
        for k in range(4, len(mus) + 1):
            bound = sigma4_bound(mus[:k], y[:k], min_t_ratio=1.05)
            assert bound == math.inf or bound < mu_star, (act, mus[k - 1], bound)
            # the policy never steps past it
            nxt = next_measurement(mus[:k], y[:k], max_step=0.2, min_t_ratio=1.05)
            assert nxt.mu < min(bound, mu_star)
        assert sigma4_bound(mus, y, min_t_ratio=1.05) < mu_star  # it does engage near mu*


def test_warn_asymmetric_never_crosses_mu_star_and_finds_it() -> None:
    res = warn("asymmetric", seed=11, max_measurements=18)
    truth = res.truth
    assert res.stopped in ("converged", "budget")
    assert truth["max_mu_measured"] < truth["mu_star"]
    assert res.prediction.transition == "saddle-node"
    assert abs(truth["error"]) < 1e-4
    assert len(res.measurements) <= 18
    for key in ("mu", "omega", "sigma2", "sigma2_std", "w_static"):
        assert all(math.isfinite(getattr(m, key)) for m in res.measurements)
    assert math.isfinite(res.prediction.baseline.mu_star)
    # the alarm rises as the strip slows down
    ratios = [a.t_ratio for a in res.alarm]
    assert ratios[-1] > 5 and ratios[-1] == max(ratios)
    # the danger rises as the sweep nears mu*: the last step of 0.2 would reach the interval
    ranks = [a.rank for a in res.alarm]
    assert ranks == sorted(ranks) and res.alarm[-1].level == "critical"
    assert res.alarm[-1].steps_left < 1
    assert res.alarm[-1] == res.prediction.alarm  # one alarm per document


@pytest.mark.slow
@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_warn_meets_the_accuracy_target(actuation: str) -> None:
    """Issue target: |mu* error| <= 1e-5 from at most 30 impulse responses at 40 dB."""
    res = warn(actuation, seed=3, max_measurements=30)
    t = res.truth
    assert abs(t["error"]) <= 1e-5
    assert t["transition_correct"]
    assert t["max_mu_measured"] < t["mu_star"]


@pytest.mark.slow
def test_warn_interval_covers_mu_star_over_seeds() -> None:
    """The 95 % interval of warn's final prediction over 12 seeds x 3 actuations covers mu* at
    least as often as a 95 % interval would with probability 0.99 (binomial lower bound,
    computed; a calibrated interval misses one seed in twenty, so one seed alone says little).
    Measured: 32 of 36."""
    from scipy import stats

    seeds, acts = range(12), ("asymmetric", "symmetric", "antisymmetric")
    covered = sum(
        bool(warn(a, seed=s, max_measurements=30).truth["covered"])
        for a in acts
        for s in seeds
    )
    n = len(seeds) * len(acts)
    assert covered >= stats.binom.ppf(0.01, n, 0.95)  # 31 of 36: P(X <= 30) = 0.8 %


def _lab_records(actuation: str, mus: np.ndarray, *, deg: float, seconds: float):
    """Beam records in a lab's units: control in degrees, time in seconds."""
    out = []
    for k, m in enumerate(mus):
        sig = simulate(Scene(actuation=actuation, mu=float(m), kick=1e-3, snr_db=50.0, seed=k))
        out.append((sig.w, sig.dt * seconds, float(m) * deg))
    return out


def test_sweep_from_signals_is_unit_agnostic() -> None:
    """The same records in degrees and seconds give mu* in degrees (scaled exactly)."""
    mu_star = bifurcation("symmetric").mu_star
    mus = mu_star - np.geomspace(0.3, 3e-3, 9)
    deg = math.degrees(math.sqrt(1e-2))  # alpha = mu sqrt(dL/L) for dL/L = 1e-2
    seconds = 0.0123  # time scale of the strip
    res = sweep_from_signals(_lab_records("symmetric", mus, deg=deg, seconds=seconds))
    p = res.prediction
    assert p is not None
    assert p.mu_star / deg == pytest.approx(mu_star, abs=1e-3)
    lo, hi = p.mu_star_interval
    assert lo < p.mu_star < hi
    assert p.transition in ("subcritical-pitchfork", "pitchfork")
    # sigma^2 comes out in 1/s^2
    s2 = spectrum("symmetric", mus[0], "U_A", modes=1).sigma2[0] / seconds**2
    assert res.measurements[0].sigma2 == pytest.approx(s2, rel=1e-3)


def _write_records(tmp_path, mus: np.ndarray) -> list[str]:  # noqa: ANN001
    """The asymmetric beam's records at ``mus`` written as CSV files ``rec<k>.csv``; the
    manifest's rows (header first)."""
    rows = ["path,control"]
    for k, (w, dt, c) in enumerate(_lab_records("asymmetric", mus, deg=1.0, seconds=1.0)):
        f = tmp_path / f"rec{k}.csv"
        t = np.arange(w.size) * dt
        f.write_text("t,w\n" + "\n".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(t, w)) + "\n")
        rows.append(f"{f.name},{c!r}")
    return rows


def test_sweep_cli_reads_a_manifest(tmp_path, capsys) -> None:
    mu_star = bifurcation("asymmetric").mu_star
    mus = mu_star - np.geomspace(0.3, 2e-3, 8)
    rows = _write_records(tmp_path, mus)
    (tmp_path / "manifest.csv").write_text("\n".join(rows) + "\n")
    assert main(["sweep", str(tmp_path / "manifest.csv"), "--json", "--no-progress"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert {"prediction", "measurements", "detections", "flags"} <= set(doc)  # SweepResult
    assert {"transition", "mu_star", "mu_star_interval"} <= set(doc["prediction"])
    assert len(doc["detections"]) == 8 and doc["detections"][0]["name"] == "rec0.csv"
    assert doc["prediction"]["mu_star"] == pytest.approx(mu_star, abs=1e-3)


def test_sweep_sets_aside_a_record_that_cannot_be_read(tmp_path, capsys) -> None:
    """A manifest whose record has dropped samples (NaN) and one whose file is empty: both set
    aside by name with the reader's reason, the answer that of the other records alone (the
    same document to the last digit); with fewer than 3 readable records the reader's error."""
    mu_star = bifurcation("asymmetric").mu_star
    mus = mu_star - np.geomspace(0.3, 2e-3, 8)
    rows = _write_records(tmp_path, mus)
    (tmp_path / "clean.csv").write_text("\n".join(rows) + "\n")
    lines = (tmp_path / "rec0.csv").read_text().splitlines()
    lines[200] = lines[200].split(",")[0] + ",nan"  # a dropped sample
    (tmp_path / "gap.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "empty.csv").write_text("")
    bad_rows = [*rows[:3], f"gap.csv,{float(mus[3]) - 1e-3!r}", *rows[3:],
                f"empty.csv,{float(mus[5]) + 1e-4!r}"]  # fmt: skip
    (tmp_path / "lab.csv").write_text("\n".join(bad_rows) + "\n")
    assert main(["sweep", str(tmp_path / "clean.csv"), "--json", "--no-progress"]) == 0
    clean = json.loads(capsys.readouterr().out)
    assert main(["sweep", str(tmp_path / "lab.csv"), "--json", "--no-progress"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["n_set_aside"] == 2
    names = {a["name"]: a["reason"] for a in doc["set_aside"]}
    assert set(names) == {"gap.csv", "empty.csv"}
    assert "must be finite" in names["gap.csv"] and "gap.csv" in names["gap.csv"]
    assert doc["prediction"] == clean["prediction"]
    assert [m["mu"] for m in doc["measurements"]] == [m["mu"] for m in clean["measurements"]]
    # two readable records: no sweep, the first reader's error (exit 2, its field named)
    (tmp_path / "few.csv").write_text("\n".join([rows[0], rows[1], rows[2], f"gap.csv,{1.0!r}"])
                                      + "\n")
    assert main(["sweep", str(tmp_path / "few.csv"), "--json", "--no-progress"]) == 2
    assert "must be finite" in capsys.readouterr().err


def test_sweep_rejects_a_bad_manifest(tmp_path, capsys) -> None:
    (tmp_path / "m.csv").write_text("file,value\nx.csv,1\n")
    assert main(["sweep", str(tmp_path / "m.csv"), "--json"]) == 2
    assert "path,control" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("actuation", ["asymmetric", "symmetric", "antisymmetric"])
def test_normal_form_warn_intervals_cover_its_mu_star(actuation: str) -> None:
    """The normal-form records are nonlinear: with a constant response amplitude the kicked
    records' frequency shift biased mu* by -2e-6 (7-11 standard errors, 3 seeds of 3 missed);
    kicks scaled with the expected rate cubed keep the response a fixed fraction of the well.

    A calibrated 95 % interval misses one seed in 20, so three of three covered fails one run
    in seven (seed 1, symmetric, missed at 2.3 standard errors once the truncation neighbours
    changed the measurement sequence); at least two of three (one run in 140) and every error
    within 3 standard errors still fail the old bias."""
    covered = 0
    for seed in (1, 2, 3):
        res = warn(actuation, model="normal-form", seed=seed, max_measurements=30)
        t, std = res.truth, res.prediction.mu_star_std
        covered += bool(t["covered"])
        # the old bias sat 7-11 standard errors off; an unbiased estimate stays within 3
        assert abs(t["error"]) < 3 * std, (seed, t, std)
        assert abs(t["error"]) < 1e-5, (seed, t)  # the warn accuracy target
    assert covered >= 2, covered
