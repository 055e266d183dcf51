"""Lab records made independently of the product: modal physics plus a lab's impairments.

Written for tests and benches only, with numpy alone (never ``sim`` or ``service``), so that
the product is tested on data it did not make.

Physics
-------
The probe reads ``y(t) = sum_k c_k x_k(t - t_kick)`` (times a scale), each mode a damped
oscillator driven by a hammer's half-sine force pulse of duration ``tau``::

    x_k'' + 2 gamma_k x_k' + omega0_k^2 x_k = sin(pi s / tau)   for 0 <= s <= tau, 0 after,

from rest (``x_k = x_k' = 0`` at ``s = 0``). The response is the exact Duhamel convolution
with the impulse response ``(e^{s1 t} - e^{s2 t}) / (s1 - s2)``, ``s1,2 = -gamma +- sqrt(gamma^2
- omega0^2)``, evaluated in closed form for the forced part (``s < tau``) and the free
ring-down after it; velocity and acceleration are its analytic derivatives
(:func:`modal_response`).

Truth and the product's variables
---------------------------------
For the fundamental (mode 0), :class:`Truth` gives ``omega0`` (undamped, rad/s),
``omega = omega0 sqrt(1 - zeta^2)`` (damped, rad/s; ``f_hz = omega / 2 pi``), the damping
ratio ``zeta = gamma / omega0`` and the decay rate ``gamma`` (1/s). The product's detector
(``service.analysis.detect``) writes a mode as ``s^2 + p s + q = 0`` with ``p = xi = 2 gamma``
and ``sigma^2 = -q = -(gamma^2 + omega^2) = -omega0^2``: so ``Truth.sigma2 = -omega0**2`` and
``Truth.p = 2 * gamma``, in the record's time unit (seconds here; a file written in ms has
``omega`` in rad/ms, i.e. ``1e-3 x``).

Impairments (each switchable; :data:`RANGES` gives the random draws)
--------------------------------------------------------------------
quantity     displacement (mm), velocity (mm/s) or acceleration (m/s^2): analytic derivatives.
pretrigger   a fraction of the record at rest before the kick.
hum          mains hum at 50 or 60 Hz, amplitude a fraction of the response's peak, plus its
             2nd/3rd/5th harmonics (the 3rd always) with random phases.
drift        a slow baseline: an offset, a ramp and a slow sinusoidal wobble.
noise        white Gaussian noise at a per-sample SNR ``10 log10(peak^2 / (2 s^2))`` in dB,
             ``peak`` the largest |response| (as the detector counts ``A^2 / (2 s^2)``).
clipping     the sensor's range: every sample beyond ``+-R`` held at ``+-R``, ``R`` a fraction of
             the largest |value| of the record.
repeats      further hammer hits later in the record (same pulse, smaller or equal force).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

QUANTITIES = ("displacement", "velocity", "acceleration")
UNITS = {"displacement": "mm", "velocity": "mm/s", "acceleration": "m/s2"}
#: The derivative order of each quantity and its factor from the mm-based response.
_ORDER = {"displacement": 0, "velocity": 1, "acceleration": 2}
_TO_UNIT = {"displacement": 1.0, "velocity": 1.0, "acceleration": 1e-3}  # mm/s^2 -> m/s^2
IMPAIRMENTS = ("pretrigger", "hum", "drift", "noise", "clipping", "repeats")

#: Random-draw ranges (uniform unless said otherwise).
RANGES: dict[str, Any] = {
    "f1_hz": (3.0, 30.0),  # fundamental (log-uniform)
    "ratio2": (2.2, 4.0),  # f2 / f1
    "ratio3": (4.5, 9.0),  # f3 / f1
    "zeta1": (0.003, 0.05),  # fundamental's damping ratio (log-uniform)
    "zeta_hi": (0.003, 0.03),  # higher modes' damping ratio (log-uniform)
    "coef_hi": (0.3, 1.0),  # |c_k| of the higher modes (c_0 = 1), random sign
    "rates_hz": (1000.0, 1024.0, 2000.0, 2048.0, 2500.0, 3000.0, 4000.0, 5000.0),
    "cycles": (30.0, 100.0),  # fundamental cycles in the record (length clipped below)
    "duration_s": (1.0, 12.0),
    "max_samples": 16000,  # (longer records make the bench hours long on a shared machine)
    "pulse_s": (2e-3, 30e-3),
    "peak_mm": (0.05, 2.0),  # peak displacement (log-uniform)
    "pretrigger": (0.02, 0.30),
    "hum": (0.005, 0.10),  # of the peak
    "mains_hz": (50.0, 60.0),
    "harmonics": {2: (0.0, 0.3), 3: (0.2, 0.6), 5: (0.0, 0.3)},  # of the hum's amplitude
    "offset": (-1.0, 1.0),  # of the peak
    "ramp": (0.0, 0.2),  # change over the record, of the peak
    "wobble": (0.0, 0.1),  # of the peak
    "wobble_hz": (0.05, 0.5),
    "snr_db": (15.0, 40.0),
    "clip": (0.6, 0.9),  # sensor range, of the largest |value|
    "repeats": (1, 2),  # further kicks
    "repeat_force": (0.3, 1.0),
}


@dataclass(frozen=True)
class Modes:
    """A structure seen by one probe: per mode the undamped frequency (Hz), the damping ratio
    and the probe's coefficient ``c_k`` (mode 0 is the fundamental)."""

    f0_hz: tuple[float, ...]
    zeta: tuple[float, ...]
    coef: tuple[float, ...]


@dataclass(frozen=True)
class Truth:
    """The fundamental's truth (see the module docstring for the product's variables)."""

    f_hz: float  # damped frequency, Hz
    omega: float  # damped angular frequency, rad/s
    omega0: float  # undamped angular frequency, rad/s
    zeta: float  # damping ratio
    gamma: float  # decay rate, 1/s
    sigma2: float  # the product's sigma^2 = -(gamma^2 + omega^2) = -omega0^2, 1/s^2
    p: float  # the product's p = xi = 2 gamma, 1/s
    static: float | None = None  # static deflection (mm), displacement records only

    @staticmethod
    def of(modes: Modes, static: float | None = None) -> Truth:
        w0 = 2.0 * math.pi * modes.f0_hz[0]
        z = modes.zeta[0]
        om = w0 * math.sqrt(max(0.0, 1.0 - z * z))
        g = z * w0
        return Truth(om / (2 * math.pi), om, w0, z, g, -(w0 * w0), 2.0 * g, static)


@dataclass(frozen=True)
class Lab:
    """Everything a record's synthesis needs beyond the modes (``None``/0: impairment off)."""

    quantity: str = "displacement"
    fs: float = 2000.0  # Hz
    duration: float = 4.0  # s
    pulse_s: float = 15e-3
    peak_mm: float = 0.3  # peak displacement of the first kick's response
    pretrigger: float = 0.0  # fraction of the record before the kick
    hum: float = 0.0  # amplitude of the mains line, fraction of the response's peak
    mains_hz: float = 50.0
    harmonics: tuple[tuple[int, float], ...] = ((3, 0.3),)  # (order, fraction of the hum)
    hum_phases: tuple[float, ...] = ()  # one per line (fundamental first); drawn when empty
    offset: float = 0.0  # fraction of the peak
    ramp: float = 0.0
    wobble: float = 0.0
    wobble_hz: float = 0.2
    snr_db: float | None = None
    clip: float | None = None  # sensor range, fraction of the largest |value|
    kicks: tuple[tuple[float, float], ...] = ()  # further kicks: (time fraction, force ratio)
    static_mm: float = 0.0  # added to a displacement record (the equilibrium deflection)
    gain: float | None = None  # fixed hammer: response = gain x modal response (mm); else peak_mm
    wobble_phase: float | None = None  # drawn when None


@dataclass(frozen=True)
class LabRecord:
    """One record: ``y`` sampled at ``t`` (s, from 0, step ``dt``), its quantity and unit, the
    fundamental's truth, the lab settings and the separate parts (before clipping)."""

    t: np.ndarray
    y: np.ndarray
    dt: float
    quantity: str
    unit: str
    truth: Truth
    modes: Modes
    lab: Lab
    kick_index: int  # first sample at or after the first kick
    parts: dict[str, np.ndarray] = field(repr=False, default_factory=dict)
    clipped: np.ndarray | None = field(repr=False, default=None)


def modal_response(t: np.ndarray, f0_hz: float, zeta: float, tau: float,
                   order: int = 0) -> np.ndarray:  # fmt: skip
    """The ``order``-th time derivative of ``x`` solving ``x'' + 2 g x' + w0^2 x = sin(pi t /
    tau)`` on ``[0, tau]`` (0 after), from rest at ``t = 0``; 0 for ``t <= 0``.

    Exact: with ``lam = +-i pi / tau`` and the poles ``s1 != s2`` (``0 <= zeta < 1`` or ``> 1``),
    ``x = sum_lam sum_s (+-) [e^{lam u + s (t - u)} - e^{s t}] / ((lam - s)(s1 - s2) 2i)``,
    ``u = min(t, tau)``; each derivative multiplies the first exponential by ``lam`` during the
    contact and by ``s`` after, the second by ``s``.
    """
    t = np.asarray(t, dtype=float)
    w0 = 2.0 * math.pi * f0_hz
    g = zeta * w0
    root = np.sqrt(complex(g * g - w0 * w0))
    s1, s2 = -g + root, -g - root
    om = math.pi / tau
    out = np.zeros(t.shape)
    pos = t > 0
    tt = t[pos]
    u = np.minimum(tt, tau)
    contact = tt < tau
    total = np.zeros(tt.shape, dtype=complex)
    for lam, c in ((1j * om, 0.5 / 1j), (-1j * om, -0.5 / 1j)):
        for s, sign in ((s1, 1.0), (s2, -1.0)):
            a = np.exp(lam * u + s * (tt - u))
            rate = np.where(contact, lam, s)
            total += c * sign * (rate**order * a - s**order * np.exp(s * tt)) / (lam - s)
    out[pos] = (total / (s1 - s2)).real
    return out


def response(t: np.ndarray, modes: Modes, tau: float, order: int) -> np.ndarray:
    """``sum_k c_k x_k^(order)(t)``: one kick at ``t = 0`` seen by the probe."""
    y = np.zeros(np.shape(t))
    for f, z, c in zip(modes.f0_hz, modes.zeta, modes.coef, strict=True):
        y += c * modal_response(t, f, z, tau, order)
    return y


def hum_lines(lab: Lab) -> list[tuple[float, float]]:
    """``(frequency Hz, amplitude as a fraction of the peak)`` of every mains line."""
    lines = [(lab.mains_hz, lab.hum)]
    lines += [(k * lab.mains_hz, lab.hum * a) for k, a in lab.harmonics if a > 0]
    return lines


def synthesize(modes: Modes, lab: Lab, rng: np.random.Generator) -> LabRecord:
    """The record of ``modes`` measured by ``lab`` (random phases and noise from ``rng``)."""
    n = int(round(lab.duration * lab.fs))
    dt = 1.0 / lab.fs
    t = dt * np.arange(n)
    order = _ORDER[lab.quantity]
    t_kick = lab.pretrigger * lab.duration
    k0 = int(math.ceil(t_kick / dt - 1e-9))
    # scale: the first kick's peak displacement is peak_mm (mm); other quantities derive from it
    disp = response(t - t_kick, modes, lab.pulse_s, 0)
    scale = lab.peak_mm / max(np.max(np.abs(disp)), 1e-300) if lab.gain is None else lab.gain
    unit_scale = scale * _TO_UNIT[lab.quantity]
    resp = unit_scale * response(t - t_kick, modes, lab.pulse_s, order)
    for frac, force in lab.kicks:
        resp += force * unit_scale * response(t - frac * lab.duration, modes, lab.pulse_s, order)
    peak = float(np.max(np.abs(resp)))
    lines = hum_lines(lab)
    phases = list(lab.hum_phases) or list(rng.uniform(0, 2 * math.pi, len(lines)))
    hum = np.zeros(n)
    if lab.hum > 0:
        for (f, a), ph in zip(lines, phases, strict=False):
            hum += a * peak * np.sin(2 * math.pi * f * t + ph)
    wob_phase = rng.uniform(0, 2 * math.pi) if lab.wobble_phase is None else lab.wobble_phase
    drift = peak * (lab.offset + lab.ramp * t / lab.duration
                    + lab.wobble * np.sin(2 * math.pi * lab.wobble_hz * t + wob_phase))  # fmt: skip
    static = lab.static_mm if lab.quantity == "displacement" else 0.0
    noise = np.zeros(n)
    if lab.snr_db is not None:
        noise = peak / math.sqrt(2.0) * 10 ** (-lab.snr_db / 20.0) * rng.standard_normal(n)
    y = static + resp + hum + drift + noise
    clipped = None
    if lab.clip is not None:
        r = lab.clip * float(np.max(np.abs(y)))
        clipped = np.abs(y) >= r
        y = np.clip(y, -r, r)
    truth = Truth.of(modes, lab.static_mm if lab.quantity == "displacement" else None)
    parts = {"response": resp, "hum": hum, "drift": drift, "noise": noise}
    return LabRecord(t, y, dt, lab.quantity, UNITS[lab.quantity], truth, modes, lab,
                     min(k0, n - 1), parts, clipped)  # fmt: skip


def _loguniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_modes(rng: np.random.Generator, f1_hz: float | None = None) -> Modes:
    """2 or 3 modes: a fundamental and stiffer higher modes (:data:`RANGES`)."""
    f1 = _loguniform(rng, *RANGES["f1_hz"]) if f1_hz is None else f1_hz
    n = int(rng.integers(2, 4))
    fs = [f1, f1 * rng.uniform(*RANGES["ratio2"])]
    if n == 3:
        fs.append(f1 * rng.uniform(*RANGES["ratio3"]))
    zs = [_loguniform(rng, *RANGES["zeta1"])]
    zs += [_loguniform(rng, *RANGES["zeta_hi"]) for _ in fs[1:]]
    cs = [1.0] + [float(rng.choice([-1, 1]) * rng.uniform(*RANGES["coef_hi"])) for _ in fs[1:]]
    return Modes(tuple(fs), tuple(zs), tuple(cs))


def _switch(rng: np.random.Generator, value: Any, p_on: float) -> bool:
    """``True``/``False`` force the impairment; ``None`` draws it on with probability p_on;
    a number forces it on with that value."""
    if value is None:
        return bool(rng.uniform() < p_on)
    return value is not False


def _value(rng: np.random.Generator, value: Any, key: str) -> float:
    if value is True or value is None:
        return float(rng.uniform(*RANGES[key]))
    return float(value)


def draw_lab(rng: np.random.Generator, modes: Modes, *, quantity: str | None = None,
             pretrigger: Any = None, hum: Any = None, drift: Any = None, noise: Any = None,
             clipping: Any = None, repeats: Any = None, p_on: float = 0.5,
             **fixed: Any) -> Lab:  # fmt: skip
    """Draw a lab's settings for ``modes``. Each impairment switch is ``None`` (on with
    probability ``p_on``), ``True``/``False`` (forced), or a number (forced on at that value:
    pretrigger fraction, hum fraction, snr in dB, clip fraction, number of repeats); ``drift``
    takes ``True``/``False``/``None``. ``fixed`` overrides any :class:`Lab` field after the draw.
    """
    q = quantity or str(rng.choice(QUANTITIES))
    f1 = modes.f0_hz[0]
    fs = float(rng.choice(RANGES["rates_hz"]))
    dur = float(np.clip(rng.uniform(*RANGES["cycles"]) / f1, *RANGES["duration_s"]))
    dur = min(dur, RANGES["max_samples"] / fs)
    kw: dict[str, Any] = {"quantity": q, "fs": fs, "duration": dur,
                          "pulse_s": float(rng.uniform(*RANGES["pulse_s"])),
                          "peak_mm": _loguniform(rng, *RANGES["peak_mm"])}  # fmt: skip
    if _switch(rng, pretrigger, p_on):
        kw["pretrigger"] = _value(rng, pretrigger, "pretrigger")
    if _switch(rng, hum, p_on):
        kw["hum"] = _value(rng, hum, "hum")
        kw["mains_hz"] = float(rng.choice(RANGES["mains_hz"]))
        kw["harmonics"] = tuple((k, float(rng.uniform(*r))) for k, r in RANGES["harmonics"].items())
    if _switch(rng, drift, p_on):
        kw["offset"] = float(rng.uniform(*RANGES["offset"]))
        kw["ramp"] = float(rng.uniform(*RANGES["ramp"]))
        kw["wobble"] = float(rng.uniform(*RANGES["wobble"]))
        kw["wobble_hz"] = float(rng.uniform(*RANGES["wobble_hz"]))
    if _switch(rng, noise, p_on):
        kw["snr_db"] = _value(rng, noise, "snr_db")
    if _switch(rng, clipping, p_on):
        kw["clip"] = _value(rng, clipping, "clip")
    if _switch(rng, repeats, p_on):
        count = int(rng.integers(RANGES["repeats"][0], RANGES["repeats"][1] + 1))
        if not isinstance(repeats, bool) and repeats is not None:
            count = int(repeats)
        start = kw.get("pretrigger", 0.0)
        fr = sorted(start + (1 - start) * rng.uniform(0.3, 0.8, count))
        kw["kicks"] = tuple((float(f), float(rng.uniform(*RANGES["repeat_force"]))) for f in fr)
    kw.update(fixed)
    return Lab(**kw)


def draw_record(seed: int | np.random.Generator, **switches: Any) -> LabRecord:
    """One random lab record with its truth: modes by :func:`draw_modes`, settings by
    :func:`draw_lab` (``switches``: ``quantity=``, the impairments, ``p_on=``, Lab fields).

    ``draw_record(seed, pretrigger=False, hum=False, drift=False, noise=False, clipping=False,
    repeats=False, quantity="displacement")`` is a clean noise-free displacement record (the
    hammer's contact still in it, at its start)."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    modes = draw_modes(rng)
    return synthesize(modes, draw_lab(rng, modes, **switches), rng)


def settings(rec: LabRecord) -> dict[str, Any]:
    """The record's drawn settings, flat (for tables)."""
    lab = rec.lab
    return {
        "quantity": lab.quantity, "fs": lab.fs, "duration": lab.duration, "n": rec.y.size,
        "pulse_ms": 1e3 * lab.pulse_s, "pretrigger": lab.pretrigger, "hum": lab.hum,
        "mains_hz": lab.mains_hz if lab.hum else 0.0, "offset": lab.offset, "ramp": lab.ramp,
        "wobble": lab.wobble, "snr_db": lab.snr_db if lab.snr_db is not None else math.inf,
        "clip": lab.clip if lab.clip is not None else 0.0, "kicks": len(lab.kicks) + 1,
        "n_modes": len(rec.modes.f0_hz), "f2_hz": rec.modes.f0_hz[1],
    }  # fmt: skip
