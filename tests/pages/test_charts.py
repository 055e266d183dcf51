"""Charts: the numbers they draw (closed forms), the names and units on their axes, and the
CLI's ``--plot`` on files as labs write them."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from service.charts import SweepSeries, label, model_curve, sweep_chart
from service.charts.cli import branch_figure, plot_file
from service.schemas.analysis import Mode, PaperRule, Prediction

SNAPWARN = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())"]


def _mode(**kw: float | str | None) -> Mode:
    base = {"omega": 0.0, "frequency": 0.0, "damping": 0.0, "sigma2": -1.0, "amplitude": 0.0,
            "phase": 0.0}  # fmt: skip
    return Mode(**{**base, **kw})


def test_model_curve_is_the_detectors_model_in_closed_form() -> None:
    """Underdamped: A exp(-g t) cos(w t + p); overdamped: b1 exp(p1 t) + b2 exp(p2 t)."""
    t = np.linspace(0.0, 20.0, 2001)
    under = _mode(omega=3.0, damping=0.1, amplitude=0.05, phase=0.4, sigma2=-9.01)
    over = _mode(regime="overdamped", real_poles=(-0.2, -1.5), real_amplitudes=(0.05, -0.02),
                 damping=0.85, amplitude=0.05, sigma2=-0.3)  # fmt: skip
    got = model_curve(t, [under, over], 0.3)
    want = (0.3 + 0.05 * np.exp(-0.1 * t) * np.cos(3.0 * t + 0.4)
            + 0.05 * np.exp(-0.2 * t) - 0.02 * np.exp(-1.5 * t))  # fmt: skip
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def test_model_curve_over_a_detection_leaves_only_the_noise() -> None:
    """The fit drawn over a record: the residual is the added noise (its std within 3 %)."""
    from service.analysis.detect import detect

    rng = np.random.default_rng(7)
    dt = 0.01
    t = np.arange(6000) * dt
    w = (-0.4 + 0.02 * np.exp(-0.05 * t) * np.cos(2.0 * t + 1.0)
         + 0.004 * np.exp(-0.2 * t) * np.cos(7.3 * t))  # fmt: skip
    noise = 2e-4 * rng.standard_normal(t.size)
    det = detect(w + noise, dt=dt)
    resid = w + noise - model_curve(t, det.modes, det.static_level)
    assert resid.std() == pytest.approx(noise.std(), rel=0.03)


def _fold_series(**units: str | None) -> SweepSeries:
    """sigma^2 = -(mu* - mu)^(1/2) (a = 1/4): T^(-1/a) is linear in mu, zero at mu* = 2."""
    mu = np.array([0.0, 0.8, 1.4, 1.7, 1.85, 1.93])
    s2 = -np.sqrt(2.0 - mu)
    pred = Prediction(mu_star=2.0, mu_star_interval=(1.999, 2.001), a=0.25,
                      transition="saddle-node", probabilities={"saddle-node": 1.0},
                      baseline=PaperRule(mu_star=2.01, stop_index=5))  # fmt: skip
    return SweepSeries.from_prediction(mu, s2, None, pred, **units)


def test_sweep_series_period_and_collapse_are_exact() -> None:
    s = _fold_series(control_name="theta", control_unit="deg", time_unit="s")
    mu = np.asarray(s.mu)
    np.testing.assert_allclose(s.period, 2 * np.pi * (2.0 - mu) ** -0.25, rtol=1e-14)
    # (T/T0)^(-1/a) = (mu* - mu) / (mu* - mu0): a straight line through zero at mu*
    np.testing.assert_allclose(s.collapse(), (2.0 - mu) / 2.0, rtol=1e-13)
    assert s.baseline_index == 5 and s.has_interval


def test_sweep_chart_carries_the_users_names_and_units() -> None:
    svg = sweep_chart(_fold_series(control_name="theta", control_unit="deg", time_unit="s"),
                      "svg").decode()  # fmt: skip
    for text in ("theta [deg]", "period T = 2 pi / omega [s]", "95 % interval of theta*",
                 "paper's rule", "distance theta* - theta [deg]", "theta - theta* [deg]",
                 "slope -a = -0.25"):  # fmt: skip
        assert text in svg, text
    assert "mu [" not in svg
    bare = sweep_chart(_fold_series(), "svg").decode()
    assert "mu (no unit given)" in bare and "period T = 2 pi / omega (no unit given)" in bare


def test_labels_never_drop_the_unit_silently() -> None:
    assert label("t", "ms") == "t [ms]"
    assert label("mu", "non-dimensional") == "mu (non-dimensional)"
    assert label("t", None) == "t (no unit given)"


def test_branch_diagram_solid_stable_dashed_unstable() -> None:
    pts = {"U_A": [(m, -0.6 + 0.1 * m, m < 1.0) for m in np.linspace(0, 2, 21)]}
    fig = branch_figure("asymmetric", pts, mu=0.5)
    lines = [ln for ln in fig.axes[0].get_lines() if ln.get_color() == "tab:blue"]
    styles = {ln.get_linestyle() for ln in lines}
    assert styles == {"-", "--"}
    solid = next(ln for ln in lines if ln.get_linestyle() == "-")
    assert max(solid.get_xdata()) == pytest.approx(1.0)  # joined to the next point


def test_plot_file_names_png_or_svg_only() -> None:
    assert plot_file("a/b.SVG") == "a/b.SVG"
    import argparse

    with pytest.raises(argparse.ArgumentTypeError, match="must end in .png or .svg"):
        plot_file("chart.pdf")


def _lab_csv(path: Path) -> Path:
    """A record as a lab logger writes it: units in the header, rounded timestamps."""
    rng = np.random.default_rng(1)
    t = np.arange(3000) * 0.1
    w = 0.2 + 0.01 * np.exp(-0.002 * t) * np.cos(0.5 * t) + 1e-4 * rng.standard_normal(t.size)
    rows = [f"{a:.1f},{float(b):.8f}" for a, b in zip(t, w)]
    path.write_text("t [ms],w [mm]\n" + "\n".join(rows) + "\n")
    return path


def test_cli_detect_plot_carries_the_files_units(tmp_path: Path) -> None:
    rec = _lab_csv(tmp_path / "rec.csv")
    out = tmp_path / "fit.svg"
    r = subprocess.run([*SNAPWARN, "detect", str(rec), "--plot", str(out)], capture_output=True,
                       text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    svg = out.read_text()
    for text in ("t [ms]", "w [mm]", "residual [mm]", "detector's fit"):
        assert text in svg, text
    period = 2 * math.pi / 0.5
    assert f"{period:.6g} ms" in svg  # the title's period in the record's unit
    bad = subprocess.run([*SNAPWARN, "detect", str(rec), "--plot", "fit.pdf"],
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert bad.returncode == 2 and "--plot" in bad.stderr and "fit.pdf" in bad.stderr


@pytest.mark.slow
def test_cli_predict_plot(tmp_path: Path) -> None:
    mu = np.array([0.0, 0.8, 1.4, 1.7, 1.85, 1.93])
    table = tmp_path / "sweep.csv"
    table.write_text("mu,sigma2\n" + "\n".join(f"{m},{-math.sqrt(2 - m)!r}" for m in mu) + "\n")
    out = tmp_path / "pred.png"
    r = subprocess.run([*SNAPWARN, "predict", str(table), "--plot", str(out)],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    svg = tmp_path / "pred.svg"
    r = subprocess.run([*SNAPWARN, "predict", str(table), "--plot", str(svg), "--control-name",
                        "V", "--control-unit", "kV", "--time-unit", "s"],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "V [kV]" in svg.read_text() and "period T = 2 pi / omega [s]" in svg.read_text()
