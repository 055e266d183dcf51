"""Figure plumbing shared by every chart: Agg figures, PNG/SVG bytes, axis labels with units."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

MEDIA = {"png": "image/png", "svg": "image/svg+xml"}
FORMATS = tuple(MEDIA)

#: Label of quantities that carry no physical unit (the simulator's non-dimensional scales).
NONDIM = "non-dimensional"


def figure(width: float = 7.0, height: float = 4.2, dpi: int = 110) -> Any:
    """A matplotlib ``Figure`` on the Agg canvas (no pyplot state, thread-safe)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=dpi, layout="constrained")


def to_bytes(fig: Any, fmt: str) -> bytes:
    """The figure as PNG or SVG bytes. SVG keeps its text as text (searchable, small)."""
    if fmt not in MEDIA:
        raise ValueError(f"fmt must be one of {FORMATS}, got fmt={fmt!r}")
    import matplotlib

    buf = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "snapwarn"}):
        fig.savefig(buf, format=fmt)
    return buf.getvalue()


def format_of(path: str | Path, option: str = "--plot") -> str:
    """``"png"`` or ``"svg"`` from a file name; ``ValueError`` naming the option otherwise."""
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in MEDIA:
        raise ValueError(f"{option}: {str(path)!r} must end in .png or .svg")
    return suffix


def write(fig: Any, path: str | Path, option: str = "--plot") -> Path:
    """Save ``fig`` to ``path`` (format from its suffix); the folder is created."""
    fmt = format_of(path, option)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(to_bytes(fig, fmt))
    return p


def label(name: str, unit: str | None) -> str:
    """``"theta [deg]"``; ``"mu (non-dimensional)"`` when the unit is the simulator's;
    ``"t (no unit given)"`` when the data did not say (never a silent bare name)."""
    if not unit:
        return f"{name} (no unit given)"
    if unit == NONDIM:
        return f"{name} ({NONDIM})"
    return f"{name} [{unit}]"


def per_time(time_unit: str | None) -> str | None:
    """The unit of a rate: ``"1/s"``; None when the time unit is unknown."""
    if not time_unit:
        return None
    if time_unit == NONDIM:
        return NONDIM
    return f"1/{time_unit}"


def fmt_num(x: float | None, digits: int = 6) -> str:
    """A number for a legend or a table: ``"-"`` when missing or not finite."""
    if x is None or not math.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"
