"""Charts of the API's routes (matplotlib, Agg), drawn by ``service.charts``: no physics, only
what the documents hold."""

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


def sweep_plot(
    doc: dict[str, Any],
    *,
    title: str,
    fmt: str = "png",
    control_name: str = "mu",
    control_unit: str | None = None,
    time_unit: str | None = None,
) -> bytes:
    """The sweep chart of a stored sweep document (``service.charts``): the period T(mu), the
    T^(-1/a) collapse with the extrapolation, the 95 % interval, the paper's rule and a zoom
    near mu*, labelled with the user's control name and units and the records' time unit."""
    from service.charts import SweepSeries, sweep_chart
    from service.convert import sweep_document

    s = SweepSeries.from_result(
        sweep_document(doc),
        control_name=control_name,
        control_unit=control_unit,
        time_unit=time_unit,
    )
    return sweep_chart(s, fmt, title=title)
