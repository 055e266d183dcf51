"""The method table: name -> fit function (``(record, dt, options) -> Outcome``).

A new method is a function here (or in its own module) and a row of :data:`METHOD_TABLE`;
:data:`METHODS` (the accepted names, with the ``"auto"`` alias) follows the table.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from service.analysis.common import Flag
from service.analysis.detect._flags import _linearity_flag
from service.analysis.detect._kernels import model_values
from service.analysis.detect._modes import (
    _ambient_errors,
    _model_at_lag0,
    _modes_from_fit,
    _pole_growth,
)
from service.analysis.detect._results import Mode
from service.analysis.detect._spectral import (
    _fft_modes,
    _head_peaks,
    _initial_candidates,
    _Spectrum,
    _spectrum,
)
from service.analysis.detect._varpro import (
    _Fit,
    _levenberg_marquardt,
    _merge_close_modes,
    _mode_energy,
    _order,
    _prune,
    _repair_real_poles,
)


@dataclass(frozen=True)
class Options:
    """Options of a fit (validated by :func:`service.analysis.detect.detect`)."""

    max_modes: int
    common: bool
    max_iter: int
    check_linearity: bool
    #: extra initial poles ``(p, q)`` in sample units (stationary lines seen before the kick
    #: or given by the user), added to the candidates of the parametric methods
    seeds: tuple[np.ndarray, np.ndarray] | None = None


@dataclass
class Record:
    """A record prepared for the methods (see :func:`service.analysis.detect._core._prepare`).

    ``x`` is the mean-removed record divided by the power of two ``unit`` (so that no square
    overflows), ``y`` the analysed sequence (``x`` itself, or its autocorrelation for ambient
    records) divided by its rms ``scale``; ``mean`` is the record's mean in units of ``x``.
    """

    x: np.ndarray
    y: np.ndarray
    scale: float
    mean: float
    unit: float
    kind: str
    max_modes: int
    spec: _Spectrum
    acf0: float = 0.0
    static_std: float | None = None
    flags: list[Flag] = field(default_factory=list)


@dataclass
class Outcome:
    """What a method returns: modes in the record's units (time unit of ``dt``, amplitudes in
    units of ``Record.x``), the noise std, the static level and its error (units of ``x``)."""

    modes: list[Mode]
    noise_std: float
    static: float
    static_std: float
    flags: list[Flag] = field(default_factory=list)
    iterations: int = 0
    ambient_var: float = 0.0
    #: per mode, the growth rate of its envelope and its standard error (parametric impulse
    #: fits; see :func:`service.analysis.detect._modes._pole_growth`), else None
    growth: list[tuple[float, float]] | None = None


def _fft(rec: Record, dt: float, opts: Options, *, parabolic: bool) -> Outcome:
    """The paper's FFT peak (``parabolic``: with sub-bin interpolation)."""
    modes, flags = _fft_modes(rec.y, dt, rec.scale, parabolic, rec.spec)
    noise_std = math.sqrt(rec.spec.noise_var) * rec.scale
    return Outcome(modes, noise_std, rec.mean, noise_std / math.sqrt(rec.x.size), flags)


def _parametric(rec: Record, dt: float, opts: Options, *, refine: bool) -> Outcome:
    """ESPRIT initialisation, then (``refine``) variable-projection least squares."""
    y, scale, N0 = rec.y, rec.scale, rec.x.size
    fit, energy = _fit_parametric(
        y, rec.spec, max_modes=rec.max_modes, common=opts.common, refine=refine,
        max_iter=opts.max_iter, seeds=opts.seeds,
    )  # fmt: skip
    if fit is None:
        noise_std = math.sqrt(float(np.mean(y * y))) * scale
        return Outcome([], noise_std, rec.mean, noise_std / math.sqrt(N0))
    fit, energy = _order(fit, energy)
    modes, c0, static_std = _modes_from_fit(fit, energy, dt, scale)
    out = Outcome(modes, math.sqrt(fit.s2) * scale, rec.mean + c0 * scale, static_std)
    out.iterations = fit.iterations
    if rec.kind == "ambient":
        out.modes = _ambient_errors(rec.x, fit, y.size, scale, dt, modes, opts.max_iter)
        # white measurement noise is the spike of the autocorrelation at lag 0
        m0 = _model_at_lag0(fit) * scale
        out.noise_std = math.sqrt(max(rec.acf0 - m0, 0.0))
        out.ambient_var = max(m0, 0.0)
    else:
        out.growth = _pole_growth(fit, dt, y)
        if opts.check_linearity and refine:
            fl = _linearity_flag(y, fit, dt, opts.max_iter)
            if fl is not None:
                out.flags.append(fl)
    return out


Method = Callable[[Record, float, Options], Outcome]

#: name -> fit function. ``"auto"`` is an alias of ``"varpro"`` (see :data:`ALIASES`).
METHOD_TABLE: dict[str, Method] = {
    "varpro": partial(_parametric, refine=True),
    "esprit": partial(_parametric, refine=False),
    "fft": partial(_fft, parabolic=False),
    "fft-parabolic": partial(_fft, parabolic=True),
}
ALIASES = {"auto": "varpro"}
METHODS = ("auto", *METHOD_TABLE)


def _fit_parametric(
    y: np.ndarray,
    spec: _Spectrum,
    *,
    max_modes: int,
    common: bool,
    refine: bool,
    max_iter: int,
    seeds: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[_Fit | None, np.ndarray]:
    """ESPRIT initialisation, MDL pruning, varpro fit; then up to two rounds of residual
    ESPRIT (multi-scale: a slow residual gets a long strided window) to add missed modes."""
    p, q = _initial_candidates(y, spec, max_modes)
    if seeds is not None and seeds[0].size:
        # a seed that a candidate already holds (within a bin) would be fitted twice
        om = np.sqrt(np.maximum(q - 0.25 * p * p, 0.0))
        bin_ = 2 * np.pi / y.shape[0]
        new = [k for k in range(seeds[0].size)
               if not np.any(np.abs(om - math.sqrt(seeds[1][k])) < bin_)]  # fmt: skip
        p = np.concatenate((p, seeds[0][new]))
        q = np.concatenate((q, seeds[1][new]))
    fit: _Fit | None = None
    energy = np.zeros(0)
    for round_ in range(3):
        p, q, energy, c_init = _prune(y, p, q, spec.noise_var, max_modes)
        if p.size == 0 and fit is None:
            if round_ > 0:
                return None, energy
        if p.size:
            new = None
            for _ in range(3):
                new = _levenberg_marquardt(
                    y,
                    p,
                    q,
                    common=common and refine,
                    max_iter=max_iter if refine else 0,
                    c0=None if common else c_init,
                )
                if new is None:
                    break
                p2, q2, energy, c_init = _prune(
                    y, new.ev.p, new.ev.q, new.s2, max_modes, G=new.ev.G
                )
                if p2.size == new.ev.p.size or p2.size == 0:
                    break
                p, q = p2, q2
            if new is not None and p2.size:
                if fit is not None and new.ev.rss >= fit.ev.rss * (1 - 1e-9):
                    break
                fit = new
            elif fit is None:
                return None, energy
        if not refine or round_ == 2:
            break
        new_p, new_q = _residual_candidates(y, fit, max_modes)
        if new_p.size == 0:
            break
        p = np.concatenate((fit.ev.p if fit is not None else np.zeros(0), new_p))
        q = np.concatenate((fit.ev.q if fit is not None else np.zeros(0), new_q))
    if fit is not None and refine:
        fit = _merge_close_modes(y, fit, max_iter)
        fit = _repair_real_poles(y, fit, max_iter)
        p2, q2, _, c2 = _prune(y, fit.ev.p, fit.ev.q, fit.s2, max_modes, G=fit.ev.G)
        if 0 < p2.size < fit.ev.p.size:
            new = _levenberg_marquardt(y, p2, q2, common=fit.common, max_iter=max_iter)
            if new is not None:
                fit = new
    if fit is not None:
        energy = _mode_energy(fit.ev) / max(fit.s2, 1e-300)
    return fit, energy


def _residual_candidates(
    y: np.ndarray, fit: _Fit | None, max_modes: int
) -> tuple[np.ndarray, np.ndarray]:
    """Candidate modes that the current fit misses: ESPRIT on the residual (and its head), and
    the peaks of the residual's head periodograms (a weak mode that decays within the record
    is seen in the head matched to its decay). Empty when the residual looks like noise."""
    N = y.shape[0]
    r = y.copy()
    base_p, base_q = np.zeros(0), np.zeros(0)
    if fit is not None:
        mv = np.empty(N)
        model_values(fit.ev.p, fit.ev.q, fit.ev.c, mv)
        r -= mv
        base_p, base_q = fit.ev.p, fit.ev.q
    rspec = _spectrum(r)
    head = r[: N // 8]
    p_new, q_new = np.zeros(0), np.zeros(0)
    if rspec.significant.any() or (
        head.size >= 128
        and float(np.mean(head * head)) > 3.0 * float(np.mean(r * r))
        and _spectrum(head).significant.any()
    ):
        p_new, q_new = _initial_candidates(r, rspec, max_modes, peaks=False)
    # head peaks that neither the fit nor the residual's ESPRIT explains
    hp, hq = _head_peaks(
        r, rspec, np.concatenate((base_p, p_new)), np.concatenate((base_q, q_new)), max_modes
    )
    return np.concatenate((p_new, hp)), np.concatenate((q_new, hq))
