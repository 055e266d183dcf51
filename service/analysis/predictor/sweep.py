"""Validated measurements along an upward sweep of the control parameter.

:func:`prepare_sweep` checks a sweep at the door (finite values, matching lengths, strictly
increasing control, stable eigenvalues, positive standard deviations) and returns a frozen
:class:`Sweep`, the input of the profile-likelihood engine (:mod:`.compare`), the
classification and the predictor. A bad value raises
:class:`service.analysis.errors.ParameterError` naming the parameter and the value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from service.analysis.common import Flag
from service.analysis.errors import ParameterError

__all__ = ["Sweep", "average_repeats", "group_mean", "prepare_sweep"]


@dataclass(frozen=True)
class Sweep:
    """Validated measurements along an upward sweep (input of the engine, the classification
    and the predictor; rebuild with ``dataclasses.replace``).

    Attributes
    ----------
    mu : ndarray, shape (n,)
        Control parameter, strictly increasing, any unit.
    y : ndarray, shape (n,)
        ``|sigma^2|`` (1/time^2), positive; for ``kind == "omega"`` this is ``omega^2``.
    sd : ndarray, shape (n,)
        Standard deviation of ``y`` (given, or estimated when ``noise_estimated``).
    kind : {"sigma2", "omega"}
        What the caller gave.
    omega, omega_sd : ndarray or None
        The observed rates (``kind == "omega"`` only).
    w, w_sd : ndarray or None
        Static deflection at the probe and its standard deviation (``None``: unknown).
    noise_given : bool
        Whether the caller gave the noise of ``sigma2`` / ``omega``.
    damping : float or None
        Damping ``xi`` (1/time) in ``s^2 + xi s - sigma^2 = 0`` when known.
    w_noise_given : bool
        False when ``w_sd`` was estimated (the static fits then profile their variance).
    """

    mu: np.ndarray
    y: np.ndarray
    sd: np.ndarray
    kind: str
    omega: np.ndarray | None
    omega_sd: np.ndarray | None
    w: np.ndarray | None
    w_sd: np.ndarray | None
    noise_given: bool
    damping: float | None
    w_noise_given: bool = True


def _as_1d(name: str, value: Any, n: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            name, value, f"{name} must be an array of numbers, got {repr(value)[:200]}"
        ) from exc
    if arr.ndim != 1:
        raise ParameterError(
            name, arr.shape, f"{name} must be one-dimensional, got shape {arr.shape}"
        )
    if n is not None and arr.size != n:
        raise ParameterError(
            name, arr.size, f"{name} must have the length of mu ({n}), got {arr.size}"
        )
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        i = int(bad[0])
        raise ParameterError(
            name, float(arr[i]), f"{name} must be finite, got {name}[{i}]={float(arr[i])!r}"
        )
    return arr


def positive_1d(name: str, value: Any, n: int) -> np.ndarray:
    """:func:`_as_1d` of length ``n`` whose values are all > 0 (rates and their stds), else a
    ``ParameterError`` naming ``name`` with the first offending value."""
    arr = _as_1d(name, value, n)
    if np.any(arr <= 0):
        i = int(np.flatnonzero(arr <= 0)[0])
        raise ParameterError(
            name, float(arr[i]), f"{name} must be > 0, got {name}[{i}]={float(arr[i])!r}"
        )
    return arr


def drop_past(
    mu: Any, sigma2: Any, *columns: Any
) -> tuple[float | None, Any, Any, tuple[Any, ...]]:
    """``(mu_past, mu, sigma2, columns)``: the rows from the first of a suffix with
    ``sigma2 >= 0`` on (:func:`past_suffix`) cut from ``mu``, ``sigma2`` and every per-row
    column (scalars and None kept), and the control of that first row (None: nothing cut)."""
    k = past_suffix(mu, sigma2) if sigma2 is not None else None
    if k is None:
        return None, mu, sigma2, columns
    n = len(mu)
    cut = [v[:k] if v is not None and np.ndim(v) == 1 and len(v) == n else v
           for v in (mu, sigma2, *columns)]  # fmt: skip
    return float(np.asarray(mu, dtype=float)[k]), cut[0], cut[1], tuple(cut[2:])


def group_mean(
    v: np.ndarray, sd: np.ndarray | None, starts: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None]:
    """Per group (rows ``starts[g]`` to ``starts[g + 1]``): the mean of ``v`` weighted by
    ``1 / sd^2`` and its standard deviation ``(sum 1 / sd^2)^(-1/2)``, or the plain mean."""
    if sd is None:
        return np.add.reduceat(v, starts) / np.diff(np.append(starts, v.size)), None
    wt = 1.0 / sd**2
    tot = np.add.reduceat(wt, starts)
    return np.add.reduceat(wt * v, starts) / tot, 1.0 / np.sqrt(tot)


def average_repeats(
    mu: Any, values: dict[str, Any], stds: dict[str, Any]
) -> tuple[Any, dict[str, Any], dict[str, Any], Flag | None]:
    """Rows that repeat the previous row's control value (a lab measuring several records at
    each mu) averaged into one row per mu: each column weighted by the inverse variance of its
    standard deviation when one is given (and given that deviation,
    ``(sum 1/std^2)^(-1/2)``), else its plain mean. ``values``: ``{name: column or None}``
    (sigma2, omega, w_static), ``stds``: their deviations by the same names (a scalar is per
    row). Anything else (no repeat, a column invalid or of another length, a control that
    falls) is returned as given, for :func:`prepare_sweep` to name. Returns ``(mu, values,
    stds, flag)``, the flag None when nothing was averaged."""
    try:
        m = np.asarray(mu, dtype=float)
        if m.ndim != 1 or m.size < 2 or not np.all(np.isfinite(m)):
            return mu, values, stds, None
        step = np.diff(m)
        if not np.any(step == 0) or np.any(step < 0):
            return mu, values, stds, None
        cols = {k: np.asarray(v, dtype=float) for k, v in values.items() if v is not None}
        sds = {}
        for k, v in stds.items():
            if v is None or values.get(k) is None:
                continue
            a = np.broadcast_to(np.asarray(v, dtype=float), m.shape)
            if not np.all(np.isfinite(a) & (a > 0)):
                return mu, values, stds, None
            sds[k] = a
    except (TypeError, ValueError):
        return mu, values, stds, None
    if any(c.shape != m.shape or not np.all(np.isfinite(c)) for c in cols.values()):
        return mu, values, stds, None
    starts = np.flatnonzero(np.r_[True, step != 0])
    if starts.size < 3:
        raise ParameterError(
            "mu", int(starts.size),
            f"mu needs at least 3 distinct control values, got {starts.size} in {m.size} rows "
            "(rows repeating a value are averaged into one point)",
        )  # fmt: skip
    out_v = dict(values)
    out_s = dict(stds)
    for k, c in cols.items():
        out_v[k], sd = group_mean(c, sds.get(k), starts)
        if sd is not None:
            out_s[k] = sd
    counts = np.diff(np.append(starts, m.size))
    flag = Flag(
        "repeated_points_averaged",
        f"{int(np.sum(counts > 1))} control values measured more than once ({m.size} rows): "
        "each averaged into one point"
        + (", weighted by its standard deviation" if sds else " (no standard deviation given)"),
    )
    return m[starts], out_v, out_s, flag


def past_suffix(mu: Any, sigma2: Any) -> int | None:
    """Index of the first of the last rows with ``sigma2 >= 0`` when they, and only they,
    have it (an upward sweep that stepped past its transition: the branch is unstable there);
    None otherwise (invalid columns are left for :func:`prepare_sweep` to name)."""
    try:
        m = np.asarray(mu, dtype=float)
        s2 = np.asarray(sigma2, dtype=float)
    except (TypeError, ValueError):
        return None
    if m.ndim != 1 or s2.shape != m.shape or not np.all(np.isfinite(s2)):
        return None
    pos = s2 >= 0
    if not pos.any() or not pos[-1]:
        return None
    k = int(np.flatnonzero(~pos)[-1]) + 1 if (~pos).any() else 0
    return k if k > 0 and pos[k:].all() and not pos[:k].any() else None


#: |sigma^2| at the sweep's first point below this fraction of its last, and the smallest of the
#: sweep: the records slow down toward the first point (T there >= 1.4 T at the last one)
_REVERSED_RATIO = 0.5


def _check_direction(m: np.ndarray, y: np.ndarray) -> None:
    """Refuse a sweep that slows down toward its lowest mu: the laws locate a transition beyond
    the last point, and such a sweep approaches one from above (its fit would put mu* far
    above the range, with no alarm). ``y = |sigma^2|`` (or omega^2), ``m`` increasing."""
    if y[0] < _REVERSED_RATIO * y[-1] and y[0] <= np.min(y):
        raise ParameterError(
            "mu", float(m[0]),
            f"the records slow down toward the lowest mu: T at mu={float(m[0])!r} is "
            f"{math.sqrt(y[-1] / y[0]):.3g} times T at mu={float(m[-1])!r}; the sweep "
            "approaches its transition from above (the control was lowered toward it): give "
            "-mu, the control values negated (mu* is then minus the answer)",
        )  # fmt: skip


def prepare_sweep(
    mu: Sequence[float] | np.ndarray,
    sigma2: Sequence[float] | np.ndarray | None = None,
    *,
    sigma2_std: Sequence[float] | np.ndarray | None = None,
    omega: Sequence[float] | np.ndarray | None = None,
    omega_std: Sequence[float] | np.ndarray | None = None,
    w_static: Sequence[float] | np.ndarray | None = None,
    w_static_std: Sequence[float] | np.ndarray | float | None = None,
    damping: float | None = None,
) -> Sweep:
    """Validate a sweep at the door; raise ``ValueError`` naming the parameter and the value.

    Parameters
    ----------
    mu : array_like, shape (n,)
        Control parameter, strictly increasing, n >= 3.
    sigma2 : array_like, shape (n,), optional
        Undamped eigenvalue of the fundamental (1/time^2), < 0 on the stable branch.
    sigma2_std : array_like, shape (n,), optional
        Its standard deviation, > 0.
    omega, omega_std : array_like, shape (n,), optional
        Instead of ``sigma2``: the observed angular rate (rad/time), > 0; ``sigma2 = -omega^2``.
    w_static, w_static_std : array_like, optional
        Static deflection at the probe (any length unit) and its standard deviation.
    damping : float, optional
        Damping ``xi`` (1/time), >= 0.

    Returns
    -------
    Sweep
    """
    m = _as_1d("mu", mu)
    n = m.size
    if n < 3:
        raise ParameterError("mu", n, f"mu needs at least 3 points, got {n}")
    step = np.diff(m)
    if np.any(step <= 0):
        i = int(np.flatnonzero(step <= 0)[0])
        raise ParameterError(
            "mu", float(m[i + 1]),
            f"mu must be strictly increasing (an upward sweep), got mu[{i}]={float(m[i])!r} "
            f"then mu[{i + 1}]={float(m[i + 1])!r}"
            + (
                "; the whole sweep decreases: if the transition lies below it (the control "
                "was lowered toward it), give -mu (mu* is then minus the answer)"
                if np.all(step < 0)
                else ""
            ),
        )  # fmt: skip
    if (sigma2 is None) == (omega is None):
        given = "neither" if sigma2 is None else "both"
        raise ParameterError("sigma2", given, f"give exactly one of sigma2 and omega, got {given}")
    if sigma2_std is not None and omega is not None:
        raise ParameterError(
            "sigma2_std", "given", "sigma2_std=... goes with sigma2, not with omega (use omega_std)"
        )
    if omega_std is not None and sigma2 is not None:
        raise ParameterError(
            "omega_std", "given", "omega_std=... goes with omega, not with sigma2 (use sigma2_std)"
        )
    om = om_sd = None
    if sigma2 is not None:
        s2 = _as_1d("sigma2", sigma2, n)
        pos = np.flatnonzero(s2 >= 0)
        if pos.size:
            i = int(pos[0])
            hint = (
                ": every value is >= 0; if the column holds |sigma2| = omega^2 (a squared "
                "frequency), give its negative, or the rates as omega"
                if pos.size == n
                else ""
            )
            raise ParameterError(
                "sigma2", float(s2[i]),
                f"sigma2 must be < 0 (a stable mode on the measured branch), got sigma2[{i}]="
                f"{float(s2[i])!r}{hint}",
            )  # fmt: skip
        y = -s2
        kind = "sigma2"
        sd = None
        if sigma2_std is not None:
            sd = _as_1d("sigma2_std", sigma2_std, n)
            if np.any(sd <= 0):
                i = int(np.flatnonzero(sd <= 0)[0])
                raise ParameterError(
                    "sigma2_std",
                    float(sd[i]),
                    f"sigma2_std must be > 0, got sigma2_std[{i}]={float(sd[i])!r}",
                )
    else:
        om = positive_1d("omega", omega, n)
        y = om**2
        kind = "omega"
        sd = None
        if omega_std is not None:
            om_sd = positive_1d("omega_std", omega_std, n)
            sd = np.sqrt((2 * om * om_sd) ** 2 + 2 * om_sd**4)
    _check_direction(m, y)
    w = w_sd = None
    if w_static is not None:
        w = _as_1d("w_static", w_static, n)
        if w_static_std is not None:
            w_sd = np.broadcast_to(np.asarray(w_static_std, dtype=float), (n,)).copy()
            w_sd = _as_1d("w_static_std", w_sd, n)
            if np.any(w_sd <= 0):
                i = int(np.flatnonzero(w_sd <= 0)[0])
                raise ParameterError(
                    "w_static_std", float(w_sd[i]),
                    f"w_static_std must be > 0, got w_static_std[{i}]={float(w_sd[i])!r}",
                )  # fmt: skip
        elif np.ptp(w) == 0:
            # all equal and no noise given: nothing to learn about b (and a fit whose noise
            # is read from its own scatter would be exact, its -2 log L unbounded)
            w = None
    elif w_static_std is not None:
        raise ParameterError("w_static_std", "given", "w_static_std=... was given without w_static")
    if damping is not None:
        xi = float(damping)
        if not math.isfinite(xi) or xi < 0:
            raise ParameterError(
                "damping", damping, f"damping must be finite and >= 0, got damping={damping!r}"
            )
        damping = xi
    noise_given = sd is not None
    if sd is None:
        sd = np.full(n, np.nan)  # filled by _estimate_noise
    return Sweep(m, y, sd, kind, om, om_sd, w, w_sd, noise_given, damping)
