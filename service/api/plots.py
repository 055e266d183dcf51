"""Charts of stored numbers (matplotlib, Agg). No physics: only what the documents hold."""

from __future__ import annotations

import io
import math
from typing import Any

import numpy as np

MEDIA = {"png": "image/png", "svg": "image/svg+xml"}


def _figure() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    return Figure(figsize=(7.0, 4.2), dpi=110, layout="constrained")


def _save(fig: Any, fmt: str) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt)
    return buf.getvalue()


def signal_plot(t: np.ndarray, w: np.ndarray, *, title: str, unit: str | None,
                value_unit: str | None, static_level: float | None, fmt: str = "png") -> bytes:
    """w(t), decimated to at most ~20000 points by min/max pairs; the static level if known."""
    fig = _figure()
    ax = fig.add_subplot()
    n = w.size
    if n > 20000:
        k = int(math.ceil(n / 10000))
        m = (n // k) * k
        tt = t[:m].reshape(-1, k)[:, 0].repeat(2)
        ww = np.column_stack([w[:m].reshape(-1, k).min(1), w[:m].reshape(-1, k).max(1)]).ravel()
        ax.plot(tt, ww, lw=0.6)
    else:
        ax.plot(t, w, lw=0.8)
    if static_level is not None and math.isfinite(static_level):
        ax.axhline(static_level, color="k", ls="--", lw=0.8, label="static level")
        ax.legend(loc="upper right")
    ax.set_xlabel(f"t [{unit}]" if unit else "t")
    ax.set_ylabel(f"w [{value_unit}]" if value_unit else "w")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    return _save(fig, fmt)


def _num(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _first(d: dict[str, Any], keys: tuple[str, ...]) -> Any:
    for k in keys:
        if k in d and d[k] is not None:
            return d[k]
    return None


def sweep_series(doc: dict[str, Any]) -> dict[str, Any]:
    """Pick the plotted numbers out of a sweep document (tolerant of key names)."""
    meas = doc.get("measurements") or []
    xs, ys = [], []
    for m in meas:
        if not isinstance(m, dict):
            continue
        x = _num(_first(m, ("mu", "control", "control_value", "x")))
        y = _num(_first(m, ("T", "time_scale", "timescale", "period")))
        if x is not None and y is not None:
            xs.append(x)
            ys.append(y)
    pred = doc.get("prediction") or {}
    mu_star = _num(_first(pred, ("mu_star", "mu_c", "critical")))
    interval = _first(pred, ("interval", "mu_star_interval", "ci"))
    lo = hi = None
    if isinstance(interval, (list, tuple)) and len(interval) == 2:
        lo, hi = _num(interval[0]), _num(interval[1])
    elif isinstance(interval, dict):
        lo, hi = _num(_first(interval, ("low", "lo", "lower"))), _num(
            _first(interval, ("high", "hi", "upper")))
    curve = _first(pred, ("extrapolation", "curve", "fit_curve")) or doc.get("extrapolation")
    cx = cy = None
    if isinstance(curve, dict):
        cx = _first(curve, ("mu", "x", "control"))
        cy = _first(curve, ("T", "y", "time_scale"))
    return {"x": xs, "y": ys, "mu_star": mu_star, "lo": lo, "hi": hi,
            "curve_x": cx, "curve_y": cy,
            "control_name": doc.get("control_name") or "mu"}


def sweep_plot(doc: dict[str, Any], *, title: str, fmt: str = "png") -> bytes:
    """T versus the control parameter, the extrapolated curve, mu* and its interval."""
    s = sweep_series(doc)
    fig = _figure()
    ax = fig.add_subplot()
    if s["x"]:
        ax.plot(s["x"], s["y"], "o", label="measured T")
    if s["curve_x"] and s["curve_y"]:
        cx = np.asarray(s["curve_x"], dtype=float)
        cy = np.asarray(s["curve_y"], dtype=float)
        ok = np.isfinite(cx) & np.isfinite(cy)
        ax.plot(cx[ok], cy[ok], "-", lw=1.2, label="extrapolation")
    if s["lo"] is not None and s["hi"] is not None:
        ax.axvspan(s["lo"], s["hi"], color="tab:red", alpha=0.15, label="95% interval of mu*")
    if s["mu_star"] is not None:
        ax.axvline(s["mu_star"], color="tab:red", lw=1.2, label=f"mu* = {s['mu_star']:.6g}")
    ax.set_xlabel(s["control_name"])
    ax.set_ylabel("T")
    if s["y"] and min(s["y"]) > 0:
        ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="best")
    return _save(fig, fmt)
