"""Numbers as a scientist writes them: a value rounded to its uncertainty, with its unit.

Pages, the plain CLI output and chart labels use these (JSON keeps full precision). The
uncertainty is written with two significant digits and the value to the same decimal place;
an interval's ends are rounded outward (never narrower than computed) and a safe bound's value
downward (never beyond the bound). Frequencies are also given in Hz when the time unit is known.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["decimals", "fmt", "fmt_below", "fmt_interval", "fmt_pm", "hz", "sig"]

#: Significant digits of an uncertainty.
UNC_DIGITS = 2


def _finite(x: Any) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def decimals(u: Any) -> int | None:
    """Decimal places that write ``u`` with :data:`UNC_DIGITS` significant digits (negative:
    rounding left of the point); None without a positive finite ``u``."""
    v = _finite(u)
    if v is None or v <= 0:
        return None
    return UNC_DIGITS - 1 - math.floor(math.log10(v))


def sig(x: Any, digits: int = 4) -> str:
    """``x`` with ``digits`` significant digits; ``-`` when missing or not finite."""
    v = _finite(x)
    return "-" if v is None else f"{v:.{digits}g}"


def _at(v: float, d: int, how: str = "round") -> str:
    q = 10.0**-d
    r = {"round": round, "floor": math.floor, "ceil": math.ceil}[how](v / q) * q
    return f"{r:.{max(d, 0)}f}"


def fmt(x: Any, u: Any = None, *, digits: int = 6) -> str:
    """``x`` rounded to the decimal place of its uncertainty ``u`` (``digits`` significant
    digits without one); ``-`` when missing."""
    v = _finite(x)
    if v is None:
        return "-"
    d = decimals(u)
    return f"{v:.{digits}g}" if d is None else _at(v, d)


def fmt_pm(x: Any, u: Any, *, digits: int = 6) -> str:
    """``x +- u`` (``u`` with two significant digits, ``x`` to the same place)."""
    if _finite(u) is None or (_finite(u) or 0) <= 0:
        return fmt(x, digits=digits)
    return f"{fmt(x, u)} +- {fmt(u, u)}"


def fmt_interval(lo: Any, hi: Any, u: Any = None) -> tuple[str, str]:
    """An interval's ends, rounded outward at the place of ``u`` (default: the half-width)."""
    a, b = _finite(lo), _finite(hi)
    if a is None or b is None:
        return fmt(lo), fmt(hi)
    d = decimals(u if u is not None else 0.5 * (b - a))
    if d is None:
        return f"{a:.6g}", f"{b:.6g}"
    return _at(a, d, "floor"), _at(b, d, "ceil")


def fmt_below(x: Any, u: Any = None, *, digits: int = 6) -> str:
    """A value that must stay below a bound (the next safe control): rounded down."""
    v = _finite(x)
    if v is None:
        return "-"
    d = decimals(u)
    return f"{v:.{digits}g}" if d is None else _at(v, d, "floor")


_SECONDS = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "\u00b5s": 1e-6, "ns": 1e-9,
            "min": 60.0, "h": 3600.0}  # fmt: skip


def hz(omega: Any, time_unit: str | None) -> str | None:
    """``omega`` (rad per ``time_unit``) as a frequency in Hz, 4 significant digits; None when
    the time unit is not a known unit of time."""
    v = _finite(omega)
    per = _SECONDS.get((time_unit or "").strip())
    if v is None or per is None:
        return None
    return f"{v / (2 * math.pi) / per:.4g} Hz"
