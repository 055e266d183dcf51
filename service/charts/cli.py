"""``--plot FILE.{png,svg}`` of the CLI: one call per command, the chart chosen by the command.

The commands pass the results they computed (their ``--json`` documents, or the numerics'
results); only the branch diagram gathers its own points (the equilibria along mu).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from service.charts._base import NONDIM, figure, format_of, label, write
from service.charts.detection import fit_figure, spectrum_figure
from service.charts.sweep import SweepSeries, sweep_figure
from service.schemas.analysis import Prediction, SweepResult

BRANCH_COLORS = {"U_A": "tab:blue", "U_B": "tab:orange", "S_A": "tab:green",
                 "S_B": "tab:red", "W_A": "tab:purple", "W_B": "tab:brown"}  # fmt: skip


def plot_file(text: str) -> str:
    """argparse ``type`` of ``--plot``: a file name ending in .png or .svg."""
    import argparse

    try:
        format_of(text, "--plot")
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} must end in .png or .svg") from None
    return text


def plot_detection(
    path: str,
    w: np.ndarray,
    dt: float,
    detection: Any,
    *,
    time_unit: str | None = None,
    value_unit: str | None = None,
    title: str | None = None,
) -> Path:
    """``snapwarn detect --plot``: the record, the fit over it, the residual."""
    t = dt * np.arange(np.asarray(w).size)
    fig = fit_figure(t, w, detection, time_unit=time_unit, value_unit=value_unit, title=title)
    return write(fig, path)


def plot_sweep(
    path: str,
    result: SweepResult,
    *,
    control_name: str = "mu",
    control_unit: str | None = NONDIM,
    time_unit: str | None = NONDIM,
    title: str | None = None,
) -> Path:
    """``snapwarn warn --plot`` and ``snapwarn sweep --plot``: the three-panel sweep chart."""
    s = SweepSeries.from_result(
        result, control_name=control_name, control_unit=control_unit, time_unit=time_unit
    )
    return write(sweep_figure(s, title=title), path)


def plot_prediction(
    path: str,
    mu: Sequence[float],
    sigma2: Sequence[float],
    sigma2_std: Sequence[float] | None,
    prediction: Prediction,
    *,
    control_name: str = "mu",
    control_unit: str | None = None,
    time_unit: str | None = None,
) -> Path:
    """``snapwarn predict --plot``: the sweep chart of a table of measured points."""
    s = SweepSeries.from_prediction(
        mu, sigma2, sigma2_std, prediction,
        control_name=control_name, control_unit=control_unit, time_unit=time_unit,
    )  # fmt: skip
    return write(sweep_figure(s, title="prediction from the table"), path)


def plot_prediction_table(
    path: str,
    mu: Sequence[float],
    columns: Mapping[str, Any],
    prediction: Prediction,
    *,
    control_name: str = "mu",
    control_unit: str | None = None,
    time_unit: str | None = None,
) -> Path:
    """``snapwarn predict --plot``: ``columns`` holds the table's ``sigma2`` (and
    ``sigma2_std``) or ``omega`` (``sigma^2 = -omega^2``; ``omega_std`` propagates as
    ``2 omega omega_std``)."""
    if "sigma2" in columns:
        s2 = np.asarray(columns["sigma2"], dtype=float)
        std = columns.get("sigma2_std")
    else:
        om = np.asarray(columns["omega"], dtype=float)
        s2 = -(om**2)
        std = None
        if columns.get("omega_std") is not None:
            std = 2.0 * om * np.asarray(columns["omega_std"], dtype=float)
    return plot_prediction(path, mu, s2, std, prediction, control_name=control_name,
                           control_unit=control_unit, time_unit=time_unit)


def plot_spectrum(path: str, doc: Mapping[str, Any], *, actuation: str, mu: float,
                  branch: str) -> Path:  # fmt: skip
    """``snapwarn spectrum --plot``: sigma^2 of the modes of one equilibrium."""
    fig = spectrum_figure(doc["sigma2"], title=f"{branch} ({actuation}) at mu = {mu:g}",
                          time_unit=NONDIM)  # fmt: skip
    return write(fig, path)


def branch_points(
    actuation: str, mu_max: float = 2.6, n: int = 131, stride: int = 5
) -> dict[str, list[tuple[float, float, bool]]]:
    """(mu, W(1/2), stable) of every branch on a grid of mu in [0, mu_max] (Euler beam).

    Stability (the sign of the spectrum, ``sim.euler_beam.is_stable``) is evaluated every
    ``stride`` points of a branch and on every point between two evaluations that disagree, so
    each change of stability is located to one grid step.
    """
    from sim.euler_beam import equilibria, is_stable

    eqs: dict[str, list[Any]] = {}
    for mu in np.linspace(0.0, mu_max, n):
        for e in equilibria(actuation, float(mu)):
            eqs.setdefault(e.branch, []).append(e)
    out: dict[str, list[tuple[float, float, bool]]] = {}
    for branch, es in eqs.items():
        known: dict[int, bool] = {}
        probe = sorted({*range(0, len(es), stride), len(es) - 1})
        for i in probe:
            known[i] = is_stable(es[i])
        for a, b in zip(probe[:-1], probe[1:]):
            if known[a] != known[b]:
                for i in range(a + 1, b):
                    known[i] = is_stable(es[i])
            else:
                for i in range(a + 1, b):
                    known[i] = known[a]
        out[branch] = [(float(e.mu), float(e.w_half), known[i]) for i, e in enumerate(es)]
    return out


def branch_figure(actuation: str, points: Mapping[str, Sequence[tuple[float, float, bool]]],
                  *, mu: float | None = None) -> Any:  # fmt: skip
    """The paper's Fig. 1 D-F: mid-point deflection W(1/2) of the six branches against mu,
    stable parts solid, unstable parts dashed; the mu asked for as a vertical line."""
    fig = figure(7.5, 4.8)
    ax = fig.add_subplot()
    for branch in sorted(points):
        pts = np.array(points[branch], dtype=float)
        color = BRANCH_COLORS.get(branch, "k")
        x, y, st = pts[:, 0], pts[:, 1], pts[:, 2].astype(bool)
        # split where the grid skips (branch absent) or the stability changes
        gap = np.diff(x) > 1.5 * np.median(np.diff(x)) if x.size > 2 else np.zeros(0, bool)
        cuts = np.flatnonzero(gap | (st[1:] != st[:-1])) + 1
        first = True
        for seg in np.split(np.arange(x.size), cuts):
            if seg.size == 0:
                continue
            j = seg if seg[-1] + 1 >= x.size or gap[seg[-1]] else np.append(seg, seg[-1] + 1)
            ax.plot(x[j], y[j], "-" if st[seg[0]] else "--", color=color, lw=1.4,
                    label=branch if first else None)  # fmt: skip
            first = False
    if mu is not None and math.isfinite(mu):
        ax.axvline(mu, color="0.4", lw=0.8, ls=":", label=f"mu = {mu:g}")
    ax.set_xlabel(label("mu = alpha sqrt(L / dL)", NONDIM))
    ax.set_ylabel(label("mid-point deflection W(1/2)", NONDIM))
    ax.set_title(f"equilibria, {actuation} actuation (solid: stable, dashed: unstable)",
                 fontsize=10)  # fmt: skip
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncols=2)
    return fig


def plot_equilibria(path: str, actuation: str, mu: float | None = None) -> Path:
    """``snapwarn equilibria --plot``: the branch diagram, with the asked mu marked."""
    top = max(2.6, 1.1 * mu) if mu is not None and math.isfinite(mu) else 2.6
    return write(branch_figure(actuation, branch_points(actuation, top), mu=mu), path)


def plot_snap(path: str, result: Any) -> Path:
    """``snapwarn snap --plot``: the amplitude A(t) after the release, linear and log scales,
    with the snap time (``sim.snap.SnapResult``)."""
    t = np.asarray(result.t, dtype=float)
    a = np.asarray(result.amplitude, dtype=float)
    fig = figure(9.0, 4.0)
    ax, bx = fig.subplots(1, 2)
    ax.plot(t, a, color="tab:blue", lw=1.0)
    pos = np.abs(a) > 0
    bx.semilogy(t[pos], np.abs(a[pos]), color="tab:blue", lw=1.0)
    for a_ in (ax, bx):
        if result.snap_time is not None:
            a_.axvline(result.snap_time, color="tab:red", lw=1.0, ls="--",
                       label=f"snap time {result.snap_time:.4g}")  # fmt: skip
        a_.set_xlabel(label("time T", NONDIM))
        a_.grid(alpha=0.3, which="both")
    ax.set_ylabel(label(f"A = W(X={result.probe:g}, t) - W*", NONDIM))
    bx.set_ylabel(label("|A|", NONDIM))
    if result.snap_time is not None:
        ax.legend(fontsize=8)
    side = "+" if result.mu > result.mu_star else "-"
    title = (f"{result.actuation} ({result.model}): {result.from_branch} -> "
             f"{result.to_branch} at mu = mu* {side} {result.dmu:.3g}")  # fmt: skip
    fig.suptitle(title, fontsize=10)
    return write(fig, path)
