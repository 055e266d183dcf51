"""The warning at a glance: T(mu), the T^(-1/a) collapse with its extrapolation, a zoom near mu*.

What is drawn (no physics is computed here, only what the results hold):

- the period ``T = 2 pi / omega`` of the fundamental, ``omega = sqrt|sigma^2|`` its undamped
  angular rate, in the records' time unit, versus the user's control (name and unit);
- the collapse ``(T / T0)^(-1/a)``, which the predictor's leading law makes a straight line that
  reaches zero at mu*; the extrapolation from the last measurement to mu* and to the interval's
  ends; the paper's two-point rule (first point with ``T > 10 T0`` and its left neighbour);
- ``T`` against the distance to mu* on log-log axes, where the law is a line of slope ``-a``; the
  horizontal bars show how far each distance moves across the 95 % interval.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service import numfmt
from service.charts._base import NONDIM, figure, fmt_num, label, to_bytes
from service.schemas.analysis import Prediction, SweepResult

#: The paper's threshold: stop when T exceeds 10 T(0) (Discussion).
PAPER_FACTOR = 10.0


def _f(x: Any) -> float:
    """A float, NaN for None."""
    return math.nan if x is None else float(x)


@dataclass(frozen=True)
class SweepSeries:
    """The numbers of one sweep chart.

    Attributes
    ----------
    mu : tuple of float
        Control values (user unit), increasing.
    sigma2, sigma2_std : tuple of float
        Undamped eigenvalue of the fundamental (1/time^2) and its standard error (NaN unknown).
    mu_star : float
        Predicted mu* (NaN when none).
    interval : tuple of float
        95 % interval of mu*.
    a : float
        Time exponent of the law used (NaN when none).
    transition : str
    probabilities : dict of str to float
    baseline_mu_star : float
        The paper's rule on the same data (NaN when none).
    baseline_index : int or None
        Index of its stopping point (``T > 10 T0``).
    control_name, control_unit, time_unit : str or None
        The user's names; ``"non-dimensional"`` for the simulator's scales.
    """

    mu: tuple[float, ...]
    sigma2: tuple[float, ...]
    sigma2_std: tuple[float, ...]
    mu_star: float = math.nan
    interval: tuple[float, float] = (math.nan, math.nan)
    a: float = math.nan
    transition: str = "undetermined"
    probabilities: dict[str, float] = field(default_factory=dict)
    baseline_mu_star: float = math.nan
    baseline_index: int | None = None
    control_name: str = "mu"
    control_unit: str | None = None
    time_unit: str | None = None

    # ------------------------------------------------------------------ builders
    @classmethod
    def from_result(
        cls,
        result: SweepResult,
        *,
        control_name: str = "mu",
        control_unit: str | None = None,
        time_unit: str | None = None,
    ) -> SweepSeries:
        """From the typed sweep result (``snapwarn warn/sweep --json``, a sweep's ``result``;
        a stored document goes through ``service.convert.sweep_document`` first)."""
        ms = result.measurements
        return cls.from_prediction(
            [m.mu for m in ms],
            [m.sigma2 for m in ms],
            [m.sigma2_std for m in ms],
            result.prediction,
            control_name=control_name,
            control_unit=control_unit,
            time_unit=time_unit,
        )

    @classmethod
    def from_prediction(
        cls,
        mu: Sequence[float | None],
        sigma2: Sequence[float | None],
        sigma2_std: Sequence[float | None] | None,
        prediction: Prediction | None,
        *,
        control_name: str = "mu",
        control_unit: str | None = None,
        time_unit: str | None = None,
    ) -> SweepSeries:
        """From measured points and the typed prediction (``snapwarn predict --json``)."""
        n = len(mu)
        std = list(sigma2_std) if sigma2_std is not None else [None] * n
        p = prediction
        base = p.baseline if p is not None else None
        idx = base.stop_index if base is not None else None
        return cls(
            mu=tuple(_f(x) for x in mu),
            sigma2=tuple(_f(x) for x in sigma2),
            sigma2_std=tuple(_f(x) for x in std),
            mu_star=_f(p.mu_star) if p else math.nan,
            interval=(_f(p.mu_star_interval[0]), _f(p.mu_star_interval[1])) if p
            else (math.nan, math.nan),
            a=_f(p.a) if p else math.nan,
            transition=p.transition if p else "undetermined",
            probabilities={k: float(v) for k, v in (p.probabilities if p else {}).items()
                           if v is not None},  # fmt: skip
            baseline_mu_star=_f(base.mu_star) if base is not None else math.nan,
            baseline_index=int(idx) if idx is not None and 0 < int(idx) < n else None,
            control_name=control_name,
            control_unit=control_unit,
            time_unit=time_unit,
        )

    # ------------------------------------------------------------------ derived numbers
    @property
    def period(self) -> np.ndarray:
        """``T = 2 pi / sqrt|sigma^2|`` (time unit of the records)."""
        return 2.0 * math.pi / np.sqrt(np.abs(np.asarray(self.sigma2, dtype=float)))

    @property
    def period_std(self) -> np.ndarray:
        """First-order error of T: ``T * sigma2_std / (2 |sigma^2|)`` (NaN when unknown)."""
        s2 = np.abs(np.asarray(self.sigma2, dtype=float))
        return self.period * np.asarray(self.sigma2_std, dtype=float) / (2.0 * s2)

    def collapse(self) -> np.ndarray:
        """``(T / T0)^(-1/a)``: 1 at the first point, 0 at mu* on the leading law."""
        T = self.period
        if not (math.isfinite(self.a) and self.a > 0 and T.size):
            return np.full(T.shape, math.nan)
        return (T / T[0]) ** (-1.0 / self.a)

    @property
    def has_prediction(self) -> bool:
        return math.isfinite(self.mu_star)

    @property
    def has_interval(self) -> bool:
        return all(math.isfinite(v) for v in self.interval)


def _plain_log(axis: Any) -> None:
    """Log-scale ticks at 1, 2, 5 x 10^k written as plain numbers (no crowded minor labels)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def _xlabel(s: SweepSeries) -> str:
    return label(s.control_name, s.control_unit)


def _band(ax: Any, s: SweepSeries) -> None:
    """mu*, its 95 % interval (a hatched band with edges, visible even when narrow)."""
    if s.has_interval:
        lo, hi = s.interval
        ax.axvspan(lo, hi, facecolor="tab:red", alpha=0.25, hatch="///", edgecolor="tab:red",
                   lw=0.0, label=f"95 % interval of {s.control_name}*")  # fmt: skip
        for v in (lo, hi):
            ax.axvline(v, color="tab:red", lw=0.6, ls=":")
    # labels written to the interval's half-width (service.numfmt), not to 9 digits
    half = 0.5 * (s.interval[1] - s.interval[0]) if s.has_interval else None
    if s.has_prediction:
        name = f"{s.control_name}* = {numfmt.fmt(s.mu_star, half)}"
        ax.axvline(s.mu_star, color="tab:red", lw=1.2, label=name)
    if math.isfinite(s.baseline_mu_star):
        ax.axvline(s.baseline_mu_star, color="0.35", lw=1.0, ls="--",
                   label=f"paper's rule: {numfmt.fmt(s.baseline_mu_star, half)}")  # fmt: skip


def draw_period(ax: Any, s: SweepSeries) -> None:
    """T(mu) with error bars, the 10 T0 threshold and the paper's stopping point."""
    mu = np.asarray(s.mu)
    T = s.period
    err = s.period_std
    err = np.where(np.isfinite(err), err, 0.0)
    ax.errorbar(mu, T, yerr=err, fmt="o", ms=4, color="tab:blue", label="measured period T")
    if T.size:
        ax.axhline(PAPER_FACTOR * T[0], color="0.5", lw=0.8, ls="-.", label="10 T(first)")
    if s.baseline_index is not None:
        i = s.baseline_index
        ax.plot(mu[i], T[i], "o", ms=8, mfc="none", mec="tab:red", mew=1.5,
                label="paper's stopping point")  # fmt: skip
    _band(ax, s)
    if T.size and np.all(T > 0):
        ax.set_yscale("log")
        _plain_log(ax.yaxis)
    ax.set_xlabel(_xlabel(s))
    ax.set_ylabel(label("period T = 2 pi / omega", s.time_unit))
    ax.grid(alpha=0.3, which="both")


def draw_collapse(ax: Any, s: SweepSeries) -> None:
    """(T/T0)^(-1/a) with the extrapolation to zero at mu* (and at the interval's ends)."""
    mu = np.asarray(s.mu)
    z = s.collapse()
    if not np.any(np.isfinite(z)):
        ax.text(0.5, 0.5, "no exponent a in the result", ha="center", transform=ax.transAxes)
        ax.set_xlabel(_xlabel(s))
        return
    ax.plot(mu, z, "o", ms=4, color="tab:blue", label=f"(T/T0)^(-1/a), a = {fmt_num(s.a, 3)}")
    if s.has_prediction:
        ends = [(s.mu_star, "-", f"extrapolation to {s.control_name}*")]
        if s.has_interval:
            ends += [(s.interval[0], ":", None), (s.interval[1], ":", None)]
        for end, style, name in ends:
            ax.plot([mu[-1], end], [z[-1], 0.0], style, color="tab:red", lw=1.0, label=name)
    i = s.baseline_index
    if i is not None and math.isfinite(s.baseline_mu_star):
        ax.plot([mu[i - 1], s.baseline_mu_star], [z[i - 1], 0.0], "--", color="0.35", lw=1.0,
                label="paper's two-point line")  # fmt: skip
    _band(ax, s)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_ylim(bottom=min(0.0, float(np.nanmin(z))) - 0.03, top=max(1.05, float(np.nanmax(z))))
    if s.has_prediction and s.has_interval and s.mu_star > mu[-1]:
        _collapse_inset(ax, s, float(mu[-1]), float(z[-1]))
    ax.set_xlabel(_xlabel(s))
    ax.set_ylabel("(T / T0)^(-1/a)")
    ax.grid(alpha=0.3)


def _collapse_inset(ax: Any, s: SweepSeries, mu_last: float, z_last: float) -> None:
    """An inset around mu* (a few interval widths) where the 95 % band is visible whatever
    its width: the extrapolated line crosses zero inside it. Its abscissa is mu - mu*."""
    lo, hi = s.interval
    c = s.mu_star
    half = max(4.0 * (hi - lo), 1e-12 * max(1.0, abs(c)))
    xs = np.array([-half, half])
    slope = z_last / (c - mu_last)
    top = max(slope * half, 1e-300)
    ins = ax.inset_axes((0.1, 0.1, 0.45, 0.36))  # below the data: it falls to the right
    ins.axvspan(lo - c, hi - c, facecolor="tab:red", alpha=0.25, hatch="///", edgecolor="tab:red",
                lw=0)  # fmt: skip
    for end, style in ((c, "-"), (lo, ":"), (hi, ":")):
        ins.plot(xs, z_last * (end - c - xs) / (end - mu_last), style, color="tab:red", lw=1.0)
    if math.isfinite(s.baseline_mu_star) and abs(s.baseline_mu_star - c) <= half:
        ins.axvline(s.baseline_mu_star - c, color="0.35", lw=1.0, ls="--")
    ins.axhline(0.0, color="k", lw=0.6)
    ins.set_xlim(-half, half)
    ins.set_ylim(-0.6 * top, top)
    ins.tick_params(labelsize=6)
    ins.set_xlabel(label(f"{s.control_name} - {s.control_name}*", s.control_unit), fontsize=6,
                   labelpad=1)  # fmt: skip
    ins.set_title("zoom: the 95 % interval", fontsize=7)
    ins.grid(alpha=0.3)


def draw_zoom(ax: Any, s: SweepSeries) -> None:
    """T versus the distance to mu* (log-log): the law is a line of slope -a."""
    mu = np.asarray(s.mu)
    T = s.period
    if not s.has_prediction:
        ax.text(0.5, 0.5, "no prediction in the result", ha="center", transform=ax.transAxes)
        return
    d = s.mu_star - mu
    ok = d > 0
    if not np.any(ok):
        ax.text(0.5, 0.5, "no point below mu*", ha="center", transform=ax.transAxes)
        return
    xerr = None
    if s.has_interval:
        lo, hi = s.interval
        left = np.clip(d - (lo - mu), 0.0, None)  # distance shrinks to lo - mu
        right = np.clip((hi - mu) - d, 0.0, None)
        xerr = np.vstack([np.minimum(left, d * (1 - 1e-9)), right])[:, ok]
    ax.errorbar(d[ok], T[ok], xerr=xerr, fmt="o", ms=4, color="tab:blue", ecolor="tab:red",
                elinewidth=0.8, label="measured (bars: across the 95 % interval)")  # fmt: skip
    if math.isfinite(s.a) and s.a > 0:
        k = int(np.flatnonzero(ok)[-1])
        xs = np.geomspace(d[ok].min(), d[ok].max(), 50)
        ax.plot(xs, T[k] * (xs / d[k]) ** (-s.a), "-", color="tab:red", lw=1.0,
                label=f"slope -a = -{fmt_num(s.a, 3)}")  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    _plain_log(ax.xaxis)
    _plain_log(ax.yaxis)
    ax.set_xlabel(label(f"distance {s.control_name}* - {s.control_name}", s.control_unit))
    ax.set_ylabel(label("period T", s.time_unit))
    ax.grid(alpha=0.3, which="both")


def sweep_figure(s: SweepSeries, *, title: str | None = None) -> Any:
    """Three panels: T(mu), the collapse with its extrapolation, the zoom near mu*."""
    fig = figure(15.0, 4.6)
    ax, bx, cx = fig.subplots(1, 3)
    draw_period(ax, s)
    draw_collapse(bx, s)
    draw_zoom(cx, s)
    ax.set_title(title or "critical slowing down")
    bx.set_title(f"extrapolation ({s.transition})")
    cx.set_title(f"near {s.control_name}* (log of the distance)")
    for a_, where in ((ax, "upper left"), (bx, "upper right"), (cx, "upper right")):
        if a_.get_legend_handles_labels()[0]:
            a_.legend(fontsize=7, loc=where)
    if s.time_unit == NONDIM:
        fig.suptitle("simulated: time and control in the paper's non-dimensional scales",
                     fontsize=8)  # fmt: skip
    return fig


def sweep_chart(s: SweepSeries, fmt: str = "svg", *, title: str | None = None) -> bytes:
    """:func:`sweep_figure` as PNG or SVG bytes."""
    return to_bytes(sweep_figure(s, title=title), fmt)
