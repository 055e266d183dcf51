"""A record with the detector's fit over it and the residual; the spectrum of an equilibrium.

The fitted model is rebuilt from the detection's documented parameters (``Mode``): with ``t``
measured from the first sample,

    w(t) = static_level + sum_k A_k exp(-gamma_k t) cos(omega_k t + phase_k)      (underdamped)
                        + b1 exp(p1 t) + b2 exp(p2 t)        (overdamped: real poles p1, p2)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from service.charts._base import NONDIM, figure, fmt_num, label, per_time, to_bytes


def _get(obj: Any, name: str) -> Any:
    """Attribute of a result dataclass or the same key of its JSON document."""
    return obj[name] if isinstance(obj, Mapping) else getattr(obj, name)


def model_curve(t: np.ndarray, modes: Sequence[Any], static_level: float | None) -> np.ndarray:
    """The detector's model at times ``t`` (seconds from the first sample, record units).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Time since the first sample (time unit of the record).
    modes : sequence of Mode (or their documents)
        ``omega``, ``damping``, ``amplitude``, ``phase``, ``regime``, ``real_poles``,
        ``real_amplitudes`` as documented by the detector.
    static_level : float or None
        The equilibrium offset (0 when unknown).
    """
    t = np.asarray(t, dtype=float)
    y = np.full(t.shape, float(static_level) if static_level is not None else 0.0)
    for m in modes:
        if _get(m, "regime") == "overdamped" and _get(m, "real_poles") is not None:
            p = _get(m, "real_poles")
            b = _get(m, "real_amplitudes") or (0.0, 0.0)
            for pk, bk in zip(p, b):
                if pk is not None and bk is not None:
                    y += float(bk) * np.exp(float(pk) * t)
            continue
        A, g, w, ph = (_get(m, k) for k in ("amplitude", "damping", "omega", "phase"))
        if None in (A, g, w, ph):
            continue
        y += float(A) * np.exp(-float(g) * t) * np.cos(float(w) * t + float(ph))
    return y


def _decimate(t: np.ndarray, *ys: np.ndarray, points: int = 4000) -> tuple[np.ndarray, ...]:
    """At most about ``points`` samples: min/max pairs per block keep the envelope visible."""
    n = t.size
    if n <= points:
        return (t, *ys)
    k = int(math.ceil(2 * n / points))
    m = (n // k) * k
    tt = t[:m].reshape(-1, k)[:, [0, -1]].ravel()
    out = []
    for y in ys:
        blocks = y[:m].reshape(-1, k)
        out.append(np.column_stack([blocks.min(1), blocks.max(1)]).ravel())
    return (tt, *out)


def fit_figure(
    t: np.ndarray,
    w: np.ndarray,
    detection: Any,
    *,
    time_unit: str | None = None,
    value_unit: str | None = None,
    title: str | None = None,
    small: bool = False,
) -> Any:
    """The record, the detector's fit over it, and the residual (a panel below).

    ``small=True`` draws a thumbnail (no residual panel, no legend) for tables.
    """
    t = np.asarray(t, dtype=float)
    w = np.asarray(w, dtype=float)
    kind = _get(detection, "kind") if _has(detection, "kind") else "impulse"
    fit = _fit_curve(t, detection, kind)
    tlabel = label("t", time_unit)
    wlabel = label("w", value_unit)
    keep = _first_periods(t, detection, 6)
    if small:
        return _thumbnail(t, w, fit, keep, tlabel, wlabel)
    zoom = fit is not None and keep.stop is not None and keep.stop < 0.5 * t.size
    if zoom:
        fig = figure(9.0, 7.4)
        ax, zx, rx = fig.subplots(3, 1, height_ratios=(3, 2.4, 1.3))
        rx.sharex(ax)
        zx.plot(t[keep], w[keep], ".", ms=2.5, color="0.35", label="record (samples)")
        zx.plot(t[keep], fit[keep], lw=0.9, color="tab:red", label="detector's fit")
        zx.set_ylabel(wlabel)
        zx.set_xlabel(tlabel)
        zx.set_title("the first six periods", fontsize=8)
        zx.legend(fontsize=7, loc="upper right")
        zx.grid(alpha=0.3)
    else:
        fig = figure(9.0, 5.2)
        ax, rx = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1.3))
    td, wd = _decimate(t, w)
    ax.plot(td, wd, lw=0.6, color="0.45", label="record")
    _residual_panel(ax, rx, t, w, fit, detection, kind)
    static = _get(detection, "static_level")
    if static is not None and math.isfinite(static):
        ax.axhline(static, color="k", ls="--", lw=0.7, label="static level")
    heading = _fundamental_title(detection, title, time_unit)
    if heading:
        ax.set_title(heading, fontsize=9)
    ax.set_ylabel(wlabel)
    rx.set_ylabel(label("residual", value_unit))
    rx.set_xlabel(tlabel)
    ax.legend(fontsize=7, loc="upper right")
    for a_ in (ax, rx):
        a_.grid(alpha=0.3)
    return fig


def _fit_curve(t: np.ndarray, detection: Any, kind: str) -> np.ndarray | None:
    """The detector's model over the record's times (NaN before the kick), or None."""
    modes = list(_get(detection, "modes") or [])
    if kind != "impulse" or not modes:
        return None
    tr = t - t[0]
    ts = tr - tr[_start(detection, tr.size)]
    fit = model_curve(ts, modes, _get(detection, "static_level"))
    fit[ts < 0] = np.nan  # the pre-trigger: before the kick the model says nothing
    return fit


def _thumbnail(
    t: np.ndarray, w: np.ndarray, fit: np.ndarray | None, keep: slice, tlabel: str, wlabel: str
) -> Any:
    """A table thumbnail: the first six periods with the fit, no legend."""
    fig = figure(3.2, 1.5, dpi=80)
    ax = fig.add_subplot()
    td, wd = _decimate(t[keep], w[keep], points=600)
    ax.plot(td, wd, ".", ms=1.5, color="0.35")
    if fit is not None:
        td, fd = _decimate(t[keep], fit[keep], points=600)
        ax.plot(td, fd, lw=0.8, color="tab:red")
    ax.tick_params(labelsize=6)
    ax.set_xlabel(tlabel, fontsize=6, labelpad=1)
    ax.set_ylabel(wlabel, fontsize=6, labelpad=1)
    return fig


def _residual_panel(
    ax: Any, rx: Any, t: np.ndarray, w: np.ndarray, fit: np.ndarray | None, detection: Any,
    kind: str,
) -> None:  # fmt: skip
    """The fit over the record (``ax``) and the residual with +-2 noise std (``rx``)."""
    if fit is None:
        why = "ambient record: poles from its correlation" if kind == "ambient" else "no mode"
        rx.text(0.5, 0.5, f"no fit over the record ({why})", ha="center", transform=rx.transAxes)
        return
    td, fd = _decimate(t, fit)
    ax.plot(td, fd, lw=0.9, color="tab:red", label="detector's fit")
    td, rd = _decimate(t, w - fit)
    rx.plot(td, rd, lw=0.5, color="tab:purple")
    noise = _get(detection, "noise_std") if _has(detection, "noise_std") else None
    if noise is not None and math.isfinite(noise):
        for v in (-2 * noise, 2 * noise):
            rx.axhline(v, color="k", lw=0.6, ls="--")
        rx.text(0.01, 0.95, f"dashed: +-2 x noise std ({fmt_num(noise, 3)})",
                transform=rx.transAxes, fontsize=7, va="top")  # fmt: skip


def _fundamental_title(detection: Any, title: str | None, time_unit: str | None) -> str | None:
    """The chart's title: the fundamental's period and regime when there is one."""
    f = _get(detection, "fundamental")
    if f is None:
        return title or None
    s2 = _get(f, "sigma2")
    if s2 is None or not s2 < 0:
        return None
    T = 2 * math.pi / math.sqrt(-s2)
    return (
        (title + ": " if title else "")
        + f"fundamental period 2 pi/sqrt|sigma^2| = {fmt_num(T, 6)}"
        + (f" {time_unit}" if time_unit and time_unit != NONDIM else "")
        + f" ({_get(f, 'regime')})"
    )


def _first_periods(t: np.ndarray, detection: Any, periods: float) -> slice:
    """The samples of the first ``periods`` periods of the fundamental (all without one)."""
    f = _get(detection, "fundamental") if _has(detection, "fundamental") else None
    s2 = _get(f, "sigma2") if f is not None else None
    if s2 is None or not math.isfinite(s2) or s2 >= 0:
        return slice(None)
    start = _start(detection, t.size)
    span = periods * 2 * math.pi / math.sqrt(-s2)
    n = int(np.searchsorted(t, t[start] + span)) + 1
    first = max(0, start - max(n - start, 20) // 4)  # a little of the pre-trigger too
    return slice(first, max(n, first + 20))


def _start(detection: Any, size: int) -> int:
    """The first sample the detector analysed (after a pre-trigger; 0 for older documents)."""
    start = int(_get(detection, "start") or 0) if _has(detection, "start") else 0
    return start if 0 <= start < size else 0


def _has(obj: Any, name: str) -> bool:
    return name in obj if isinstance(obj, Mapping) else hasattr(obj, name)


def fit_chart(t: np.ndarray, w: np.ndarray, detection: Any, fmt: str = "svg", **kw: Any) -> bytes:
    """:func:`fit_figure` as PNG or SVG bytes."""
    return to_bytes(fit_figure(t, w, detection, **kw), fmt)


def spectrum_figure(
    sigma2: Sequence[float],
    *,
    title: str,
    time_unit: str | None = NONDIM,
) -> Any:
    """The eigenvalues sigma^2 of an equilibrium's modes (stable: sigma^2 < 0, blue; unstable:
    red) and their angular rates sqrt|sigma^2|."""
    s2 = np.asarray(sigma2, dtype=float)
    k = np.arange(1, s2.size + 1)
    fig = figure(9.0, 3.8)
    ax, bx = fig.subplots(1, 2)
    colors = np.where(s2 < 0, "tab:blue", "tab:red")
    ax.bar(k, s2, color=colors)
    ax.axhline(0, color="k", lw=0.6)
    ax.set_yscale("symlog", linthresh=max(1.0, float(np.nanmin(np.abs(s2))) if s2.size else 1.0))
    ax.set_xlabel("mode")
    ax.set_ylabel(label("sigma^2", _squared(per_time(time_unit))))
    ax.set_title("eigenvalues (blue: stable, red: unstable)", fontsize=9)
    bx.plot(k, np.sqrt(np.abs(s2)), "o-", color="tab:blue")
    bx.set_yscale("log")
    bx.set_xlabel("mode")
    bx.set_ylabel(label("sqrt|sigma^2|", per_time(time_unit)))
    bx.set_title("angular rates", fontsize=9)
    for a_ in (ax, bx):
        a_.grid(alpha=0.3)
        a_.set_xticks(k)
    fig.suptitle(title, fontsize=10)
    return fig


def _squared(unit: str | None) -> str | None:
    if unit in (None, NONDIM):
        return unit
    return f"({unit})^2"
