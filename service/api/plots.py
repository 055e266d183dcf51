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


def signal_plot(
    t: np.ndarray,
    w: np.ndarray,
    *,
    title: str,
    unit: str | None,
    value_unit: str | None,
    static_level: float | None,
    fmt: str = "png",
) -> bytes:
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
    """Pick the plotted numbers out of a sweep document.

    Measurements give the control value (``mu``) and the time scale ``T`` (or ``omega`` =
    1/T, as the warn document holds it); the prediction gives mu*, its interval and the
    exponent ``a`` of the law T^(-1/a) ~ (mu* - mu) that the predictor extrapolated.
    """
    meas = doc.get("measurements") or []
    xs, ys = [], []
    for m in meas:
        if not isinstance(m, dict):
            continue
        x = _num(_first(m, ("mu", "control", "control_value", "x")))
        y = _num(_first(m, ("T", "time_scale", "timescale", "period")))
        if y is None:
            om = _num(m.get("omega"))
            y = 1.0 / om if om else None
        if x is not None and y is not None:
            xs.append(x)
            ys.append(y)
    pred = doc.get("prediction") or doc
    mu_star = _num(_first(pred, ("mu_star", "mu_c", "critical")))
    interval = _first(pred, ("mu_star_interval", "interval", "ci"))
    lo = hi = None
    if isinstance(interval, (list, tuple)) and len(interval) == 2:
        lo, hi = _num(interval[0]), _num(interval[1])
    elif isinstance(interval, dict):
        lo, hi = (
            _num(_first(interval, ("low", "lo", "lower"))),
            _num(_first(interval, ("high", "hi", "upper"))),
        )
    return {
        "x": xs,
        "y": ys,
        "mu_star": mu_star,
        "lo": lo,
        "hi": hi,
        "a": _num(pred.get("a")),
        "transition": pred.get("transition"),
        "control_name": doc.get("control_name") or "mu",
    }


def sweep_plot(doc: dict[str, Any], *, title: str, fmt: str = "png") -> bytes:
    """Left: T versus the control, mu* and its interval. Right: T^(-1/a) versus the control,
    where the predictor's law is a straight line to zero at mu*: the extrapolation is drawn
    from the last measurement to mu* (and to the interval's ends)."""
    s = sweep_series(doc)
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.2), dpi=110, layout="constrained")
    ax, bx = fig.subplots(1, 2)
    x = np.asarray(s["x"], dtype=float)
    y = np.asarray(s["y"], dtype=float)
    if x.size:
        ax.plot(x, y, "o", ms=4, label="measured T")
    for a_ in (ax, bx):
        if s["lo"] is not None and s["hi"] is not None:
            a_.axvspan(s["lo"], s["hi"], color="tab:red", alpha=0.15, label="95% interval")
        if s["mu_star"] is not None:
            a_.axvline(s["mu_star"], color="tab:red", lw=1.0, label=f"mu* = {s['mu_star']:.8g}")
        a_.set_xlabel(s["control_name"])
        a_.grid(alpha=0.3)
    ax.set_ylabel("T")
    if y.size and (y > 0).all():
        ax.set_yscale("log")
    a = s["a"]
    if a and x.size and (y > 0).all():
        z = y ** (-1.0 / a)
        bx.plot(x, z, "o", ms=4, label=f"T^(-1/a), a = {a:.3g}")
        if s["mu_star"] is not None:
            for end, style in ((s["mu_star"], "-"), (s["lo"], ":"), (s["hi"], ":")):
                if end is not None:
                    bx.plot([x[-1], end], [z[-1], 0.0], style, color="tab:blue", lw=1.0)
        bx.set_ylabel("T^(-1/a)")
        bx.set_ylim(bottom=0.0)
    else:
        bx.text(0.5, 0.5, "no exponent in the result", ha="center", transform=bx.transAxes)
    if s["mu_star"] is not None and s["lo"] is not None and s["hi"] is not None:
        bx.text(
            0.02,
            0.02,
            f"mu* = {s['mu_star']:.10g}\n95%: [{s['lo']:.10g}, {s['hi']:.10g}]",
            transform=bx.transAxes,
            fontsize=8,
            va="bottom",
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
        )
    ax.set_title(title)
    bx.set_title(f"extrapolation ({s['transition'] or 'undetermined'})")
    for a_ in (ax, bx):
        if a_.get_legend_handles_labels()[0]:
            a_.legend(loc="upper right" if a_ is bx else "upper left", fontsize=8)
    return _save(fig, fmt)
