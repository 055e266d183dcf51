"""The validated recording, the arrays' checks, the setting, and the downloads."""

from __future__ import annotations

import io
import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from service.analysis.common import Flag
from service.recordings._errors import RecordingError

FORMATS = ("csv", "npy", "npz", "wav", "mat")
DEFAULT_UNIFORM_RTOL = 1e-3
UNIFORM_RTOL_ENV = "SNAPWARN_UNIFORM_RTOL"


@dataclass(frozen=True)
class Recording:
    """A validated recording.

    Attributes
    ----------
    w : ndarray, shape (n,)
        The samples, float64, finite (record units: ``value_unit``).
    t : ndarray, shape (n,), or None
        The sample times as written (None when the record is defined by ``dt``, or after
        resampling). They increase strictly and are uniform within the rounding of their
        written digits.
    dt : float
        Sampling step (time unit ``unit``); least-squares when the timestamps were rounded.
    t0 : float
        Time of the first sample.
    unit, value_unit : str or None
        Units of time and of ``w``, as the file or the caller gave them.
    source : str
        ``"json"``, ``"arrays"``, or the file format.
    flags : tuple of Flag
        ``rounded_timestamps`` (dt estimated by least squares), ``resampled``, ``clipped``
        (the extremes held in several separate runs: a saturated sensor).
    metadata : dict
        What the reader learnt about the file (columns, variables, sample rate...).
    """

    w: np.ndarray
    t: np.ndarray | None
    dt: float
    t0: float
    unit: str | None = None
    value_unit: str | None = None
    source: str = "arrays"
    flags: tuple[Flag, ...] = ()
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.w.size)

    @property
    def duration(self) -> float:
        """``dt * (n - 1)``, time unit ``unit``."""
        return self.dt * (self.n - 1)

    def time(self) -> np.ndarray:
        """The sample times: ``t`` as written, else ``t0 + k dt``."""
        return time_axis(self.n, self.dt, self.t0, self.t)

    @property
    def quantity(self) -> str | None:
        """What the samples measure, read from ``value_unit`` (:func:`quantity_of`):
        ``"displacement"``, ``"velocity"``, ``"acceleration"``, or None (not said)."""
        return quantity_of(self.value_unit)


_LENGTHS = ("m", "mm", "um", "µm", "μm", "nm", "cm", "in", "mil", "ft")


def quantity_of(value_unit: str | None) -> str | None:
    """The quantity a unit measures: a length (``mm``, ``um``, ``in``...) is a displacement,
    a length per time (``mm/s``, ``in/s``) a velocity, per time squared (``m/s2``, ``m/s^2``,
    ``m/s²``, ``g``) an acceleration; None for anything else (volts, counts, no unit)."""
    if not value_unit:
        return None
    u = value_unit.strip().replace(" ", "").replace("**", "^")
    if u.lower() in ("g", "gn", "g0"):
        return "acceleration"
    num, _, den = u.partition("/")
    if num not in _LENGTHS:
        return None
    if not den:
        return "displacement"
    if den in ("s", "ms", "us", "min"):
        return "velocity"
    if den in ("s2", "s^2", "s²", "ms2", "ms^2", "ms²"):
        return "acceleration"
    return None


@dataclass
class _Raw:
    """A parsed file before validation: arrays as found, and what the file says about them."""

    w: Any
    t: Any = None
    dt: float | None = None
    unit: str | None = None
    value_unit: str | None = None
    source: str = "arrays"
    t_cells: list[str] | None = None  # the time column as written (CSV)
    metadata: dict[str, Any] = field(default_factory=dict)


def uniform_rtol_from_env(default: float = DEFAULT_UNIFORM_RTOL) -> float:
    """The uniform-sampling tolerance: ``SNAPWARN_UNIFORM_RTOL`` if set, else ``default``."""
    text = os.environ.get(UNIFORM_RTOL_ENV)
    if text is None or not text.strip():
        return default
    try:
        v = float(text)
    except ValueError:
        raise RecordingError(UNIFORM_RTOL_ENV, text, "is not a number") from None
    if not (math.isfinite(v) and v > 0):
        raise RecordingError(UNIFORM_RTOL_ENV, text, "must be a finite number > 0")
    return v


def check_finite(name: str, a: np.ndarray) -> None:
    """Raise naming the first non-finite element ``name[i]``."""
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad))
        raise RecordingError(
            f"{name}[{i}]",
            float(a[i]),
            f"must be finite ({int(bad.sum())} non-finite value(s) in {name})",
        )


def to_f64(name: str, values: Any) -> np.ndarray:
    """A 1-D float64 array from a list or an array; refuses ragged, nested, boolean, text."""
    try:
        a = np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise RecordingError(name, values, f"must be a flat list of numbers ({exc})") from None
    if a.dtype.kind == "c":
        raise RecordingError(name, str(a.dtype), "must be real, got complex values")
    if a.dtype.kind == "b":
        raise RecordingError(name, str(a.dtype), "must hold numbers, not booleans")
    if a.dtype.kind not in "iuf":
        raise RecordingError(name, str(a.dtype), "must hold numbers")
    if a.ndim != 1:
        raise RecordingError(name, list(a.shape), "must be one-dimensional")
    return a.astype(np.float64, copy=False)


def _positive_finite(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RecordingError(name, value, "must be a number") from None
    if not (math.isfinite(v) and v > 0):
        raise RecordingError(name, v, "must be a finite number > 0")
    return _representable_step(name, v)


#: A step whose square (or inverse square) is not a normal float64 cannot give a finite
#: eigenvalue (``sigma^2`` is in 1/time^2): about 3e-154 <= dt <= 3.4e153 (any time unit).
_STEP_MIN = math.sqrt(2.0**-1022) * 2.0
_STEP_MAX = 1.0 / _STEP_MIN


def _representable_step(name: str, v: float) -> float:
    if not _STEP_MIN <= v <= _STEP_MAX:
        raise RecordingError(
            name,
            v,
            f"is out of the representable range [{_STEP_MIN:.3g}, {_STEP_MAX:.3g}]: rates in "
            "1/time^2 would under- or overflow; write the record in another time unit",
        )
    return v


def time_axis(n: int, dt: float, t0: float, t: np.ndarray | None) -> np.ndarray:
    """``t`` if given, else ``t0 + k dt`` for ``k = 0..n-1``."""
    return t if t is not None else t0 + dt * np.arange(n, dtype=np.float64)


def to_csv(t: np.ndarray, w: np.ndarray, unit: str | None, value_unit: str | None) -> bytes:
    """CSV with a header; 17 significant digits, so float64 values round-trip exactly."""
    out = io.StringIO()
    th = f"t [{unit}]" if unit else "t"
    wh = f"w [{value_unit}]" if value_unit else "w"
    out.write(f"{th},{wh}\n")
    np.savetxt(out, np.column_stack([t, w]), delimiter=",", fmt="%.17g")
    return out.getvalue().encode()


def to_npy(t: np.ndarray, w: np.ndarray) -> bytes:
    """A (n, 2) float64 .npy array with columns t, w."""
    out = io.BytesIO()
    np.save(out, np.column_stack([t, w]).astype("<f8"), allow_pickle=False)
    return out.getvalue()
