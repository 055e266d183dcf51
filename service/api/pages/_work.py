"""What the pages compute off the event loop (in the analysis pool): charts and detections.

Module-level functions over plain data, so that a process pool can run them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from service.charts import SweepSeries, fit_chart, sweep_chart
from service.convert import detection as wire_detection
from service.convert import sweep_document


def inline_svg(svg: bytes) -> str:
    """An SVG document as an element to put inside HTML (no XML prolog, no DOCTYPE)."""
    text = svg.decode("utf-8")
    start = text.find("<svg")
    return text[start:] if start >= 0 else text


def sweep_svg(
    result: dict[str, Any],
    control_name: str,
    control_unit: str | None,
    time_unit: str | None,
    title: str,
) -> str:
    """The sweep's three-panel chart as inline SVG."""
    s = SweepSeries.from_result(
        sweep_document(result),
        control_name=control_name,
        control_unit=control_unit,
        time_unit=time_unit,
    )
    return inline_svg(sweep_chart(s, "svg", title=title))


def record_thumbnail(
    t: np.ndarray | None,
    n: int,
    dt: float,
    t0: float,
    w: np.ndarray,
    detection: Any,
    time_unit: str | None,
    value_unit: str | None,
) -> bytes:
    """A small fit-over-signal chart (SVG bytes) from a stored detection document."""
    tt = t if t is not None else t0 + dt * np.arange(n)
    return fit_chart(tt, w, detection, fmt="svg", time_unit=time_unit,
                     value_unit=value_unit, small=True)  # fmt: skip


def signal_analysis(
    t: np.ndarray | None,
    n: int,
    dt: float,
    t0: float,
    w: np.ndarray,
    time_unit: str | None,
    value_unit: str | None,
    title: str,
    fmt: str = "svg",
) -> tuple[dict[str, Any], bytes]:
    """Detect the record's modes (the same call as ``POST /v1/detections``) and draw the fit."""
    from service.analysis.detect import detect

    det = wire_detection(detect(np.asarray(w, dtype=float), dt=float(dt)))
    tt = t if t is not None else t0 + dt * np.arange(n)
    chart = fit_chart(tt, w, det, fmt=fmt, time_unit=time_unit, value_unit=value_unit,
                      title=title)  # fmt: skip
    return det.model_dump(mode="json"), chart


def period(sigma2: float | None) -> float | None:
    """``2 pi / sqrt|sigma^2|``; None when missing."""
    if sigma2 is None or not math.isfinite(sigma2) or sigma2 == 0:
        return None
    return 2.0 * math.pi / math.sqrt(abs(sigma2))
