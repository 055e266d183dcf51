"""A blind lab's recorder: exact modal impulse responses recorded the way other labs record them.

numpy only (never ``sim``, ``service`` or the other test generators). Each mode ``k`` of a
:class:`_blind_structures.State` is a damped oscillator ``x'' + 2 gamma x' + omega0^2 x =
c_k f(t)`` from rest, ``c_k`` its shape at the hammer times at the sensor. Everything linear is
a rational function of ``s``, so the record is the exact sum of residues

    y(t) = K sum_i p_i^m e^{p_i t} / prod_{j != i} (p_i - p_j)          (t >= 0)

of ``Y(s) = K s^m / prod_i (s - p_i)`` over the mode's poles ``-gamma +- sqrt(gamma^2 -
omega0^2)``, the hammer's poles and the sensor's poles (:func:`response`; distinct simple poles,
a nearly repeated pair is moved apart by 1e-7 relative). Checked against a numerical ODE
integration in ``test_blind_generators.py``.

What is different from tests/labrec (on purpose)
------------------------------------------------
hammer   a double-exponential force ``e^{-t/tau1} - e^{-t/tau2}`` (fast rise, slow decay:
         poles ``-1/tau1``, ``-1/tau2``), optionally a second hit ``rho`` times as strong
         ``delay`` later (a bounce).
sensor   ``laser``: displacement (static level included), in ``mm``, ``in`` or ``deg``;
         ``geophone``: velocity through the geophone's own second-order high-pass
         ``s^2 / (s^2 + 2 zeta_g omega_g s + omega_g^2)`` (4.5 Hz, 0.7), output in ``V``
         (or ``in/s``); ``accel``: acceleration in ``g``.
rig      a suspended sensor (or the frame) rings at a fixed frequency: a mode that does not
         soften with the control, possibly below the fundamental.
hum      60 Hz mains and its harmonics (US lab); a 500 Hz rate folds the 5th onto 200 Hz.
ADC      quantised to ``bits`` over a fixed range (a lab picks the range once for a sweep).
gaps     dropped samples written as ``NaN``.
AC       ``highpass_hz``: the sensor's AC coupling (an IEPE accelerometer's or an amplifier's
         first-order high-pass ``s / (s + omega_c)``, ``highpass_order`` of them in cascade): an
         LTI filter, so the structure's poles (the truth) are unchanged; it adds the real pole
         ``-omega_c`` and shifts the slow modes' amplitude and phase; a laser behind it loses its
         static level (DC is blocked).
start    ``pretrigger`` (rest before the hit) or ``midring`` (the record starts after the hit:
         no pre-trigger, no contact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

G0 = 9.80665  # m/s^2 per g
MM_PER_IN = 25.4


@dataclass(frozen=True)
class Recording:
    """How one lab records (see the module docstring). Frequencies in Hz, times in s."""

    rate_hz: float = 2000.0
    duration_s: float = 4.0
    sensor: str = "laser"  # laser | geophone | accel
    unit: str = "mm"  # laser: mm | in | deg ; geophone: V | in/s ; accel: g
    tau_decay_s: float = 2e-3
    tau_rise_s: float = 3e-4
    second_hit: tuple[float, float] | None = None  # (delay_s, relative force)
    start: str = "pretrigger"  # pretrigger | midring
    pretrigger: float = 0.1  # fraction of the record before the hit
    midring_s: float = 0.05  # the record starts this long after the hit
    peak_mm: float = 0.3  # the response's largest displacement at the first record
    geophone_hz: float = 4.5
    geophone_zeta: float = 0.7
    geophone_v_per_mps: float = 28.8
    rig: tuple[float, float, float] | None = None  # (f_Hz, zeta, amplitude rel. to peak)
    hum_rel: float = 0.0  # 60 Hz amplitude relative to the dynamic peak
    mains_hz: float = 60.0
    harmonics: tuple[float, ...] = (0.4, 0.3, 0.1, 0.2)  # 2nd..5th relative to the hum
    snr_db: float | None = 40.0
    adc_bits: int | None = None
    adc_range: float | None = None  # full scale +-range in the file's unit (None: 1.25 x peak)
    nan_gaps: int = 0
    offset: float = 0.0  # a sensor's zero offset in the file's unit
    #: the sensor's zero jumps mid-record (a re-zero, a cable knock): ``(fraction of the record,
    #: size relative to the dynamic peak)``; the values after that instant are shifted
    offset_step: tuple[float, float] | None = None
    #: the logger's sampling instants jitter (Gaussian std, s) while the file's times are the
    #: nominal grid (``stamped=False``) or the instants actually sampled (``stamped=True``:
    #: non-uniform time stamps, as a logger with its own clock writes them)
    jitter_s: float = 0.0
    jitter_stamped: bool = False
    time_unit: str = "s"  # s | ms
    #: AC coupling: corner (Hz) of ``highpass_order`` first-order high-passes ``s/(s+omega_c)``
    highpass_hz: float | None = None
    highpass_order: int = 1
    seed: int = 0


def _poles(omega0_sq: float, gamma: float) -> list[complex]:
    d = complex(gamma * gamma - omega0_sq) ** 0.5
    return [-gamma + d, -gamma - d]


def _separate(poles: list[complex]) -> list[complex]:
    """Move nearly coincident poles apart (1e-7 relative) so residues stay simple."""
    out: list[complex] = []
    for p in poles:
        scale = max(abs(p), 1e-12)
        while any(abs(p - q) < 1e-7 * scale for q in out):
            p = p * (1 + 1e-7) + 1e-7j * scale
        out.append(p)
    return out


def response(t: np.ndarray, gain: float, m: int, poles: list[complex]) -> np.ndarray:
    """Inverse Laplace transform of ``gain s^m / prod (s - p_i)`` for ``t >= 0`` (0 before).

    Requires ``m < len(poles)`` (a proper function) and distinct poles."""
    poles = _separate(list(poles))
    if m >= len(poles):
        raise ValueError("improper transfer function")
    t = np.asarray(t, float)
    y = np.zeros(t.shape, complex)
    on = t >= 0
    for i, p in enumerate(poles):
        den = np.prod([p - q for j, q in enumerate(poles) if j != i])
        y[on] += (p**m / den) * np.exp(p * t[on])
    return gain * y.real


def mode_output(t: np.ndarray, omega0_sq: float, gamma: float, c: float, rec: Recording,
                ) -> np.ndarray:  # fmt: skip
    """One mode's contribution to the sensor's output (``mm`` for a laser, ``mm/s`` through the
    geophone's response, ``mm/s^2`` for an accelerometer), hammer force of unit amplitude."""
    a, b = 1.0 / rec.tau_decay_s, 1.0 / rec.tau_rise_s
    poles = _poles(omega0_sq, gamma) + [-a, -b]
    gain = c * (b - a)
    if rec.sensor == "laser":
        m = 0
    elif rec.sensor == "accel":
        m = 2
    elif rec.sensor == "geophone":
        wg = 2 * math.pi * rec.geophone_hz
        poles += _poles(wg * wg, rec.geophone_zeta * wg)
        m = 3
    else:
        raise ValueError(f"sensor {rec.sensor!r}")
    if rec.highpass_hz:
        wc = 2 * math.pi * rec.highpass_hz
        poles += [-wc] * rec.highpass_order
        m += rec.highpass_order
    y = response(t, gain, m, poles)
    if rec.second_hit is not None:
        delay, rho = rec.second_hit
        y = y + rho * response(t - delay, gain, m, poles)
    return y


@dataclass(frozen=True)
class Record:
    """One recorded file's content and its truth."""

    t: np.ndarray  # in the file's time unit
    y: np.ndarray  # in the file's value unit (NaN where dropped)
    time_unit: str
    value_unit: str
    quantity: str  # displacement | velocity | acceleration
    truth_omega0: float  # the critical mode's undamped rate, rad/s (nan when unstable)
    truth_gamma: float  # its decay rate, 1/s
    info: dict = field(default_factory=dict)


def _to_unit(y_mm: np.ndarray, rec: Recording, deg_per_mm: float) -> tuple[np.ndarray, str, str]:
    """The output in the file's unit: ``(values, value_unit, quantity)``."""
    if rec.sensor == "laser":
        if rec.unit == "mm":
            return y_mm, "mm", "displacement"
        if rec.unit == "in":
            return y_mm / MM_PER_IN, "in", "displacement"
        if rec.unit == "deg":
            return y_mm * deg_per_mm, "deg", "displacement"
    if rec.sensor == "geophone":
        if rec.unit == "V":
            return y_mm * 1e-3 * rec.geophone_v_per_mps, "V", "velocity"
        if rec.unit == "in/s":
            return y_mm / MM_PER_IN, "in/s", "velocity"
    if rec.sensor == "accel" and rec.unit == "g":
        return y_mm * 1e-3 / G0, "g", "acceleration"
    raise ValueError(f"sensor {rec.sensor!r} with unit {rec.unit!r}")


def record(state, omega_scale: float, gamma: float, rec: Recording, force: float,
           static_mm_per_unit: float = 1.0, deg_per_mm: float = 1.0,
           adc_range: float | None = None) -> Record:  # noqa: ANN001  # fmt: skip
    """Record one impulse response of a linearised structure.

    Parameters
    ----------
    state : _blind_structures.State
        The structure at this control (non-dimensional ``omega2``).
    omega_scale : float
        rad/s per non-dimensional rate: ``omega0 = omega_scale sqrt(omega2)``.
    gamma : float
        Every mode's decay rate (1/s): mass-proportional damping, so a mode going soft becomes
        overdamped once ``omega0 < gamma``.
    force : float
        The hammer's amplitude (mm s^-2 per unit shape): one campaign keeps it fixed.
    adc_range : float, optional
        The ADC's full scale (file unit), fixed for the sweep (else ``rec.adc_range``).
    """
    rng = np.random.default_rng(rec.seed)
    n = int(round(rec.duration_s * rec.rate_hz)) + 1
    k = np.arange(n)
    if rec.start == "pretrigger":
        t_hit = rec.pretrigger * rec.duration_s
    else:
        t_hit = -rec.midring_s
    t = k / rec.rate_hz  # from the record's first sample
    t_true = t + sample_jitter(rec, n)  # the instants actually sampled
    s = t_true - t_hit  # time since the hit
    y = np.zeros(n)
    for om2, a_s, a_h in zip(state.omega2, state.at_sensor, state.at_hammer, strict=True):
        y += mode_output(s, float(om2) * omega_scale**2, gamma, force * a_s * a_h, rec)
    if rec.rig is not None:
        f_r, z_r, amp = rec.rig
        wr = 2 * math.pi * f_r
        y_r = mode_output(s, wr * wr, z_r * wr, 1.0, rec)
        peak = float(np.max(np.abs(y))) or 1.0
        y += amp * peak / max(float(np.max(np.abs(y_r))), 1e-300) * y_r
    vals, vunit, quantity, peak = finish(y, t_true, state.static * static_mm_per_unit, rec, rng,
                                         deg_per_mm, adc_range)  # fmt: skip
    crit = state.critical
    om2c = float(state.omega2[crit]) * omega_scale**2
    t_file = t_true if rec.jitter_stamped else t
    t_out = t_file * (1e3 if rec.time_unit == "ms" else 1.0)
    info = {"omega2_all": (state.omega2 * omega_scale**2).tolist(), "peak": peak}
    return Record(t_out, vals, rec.time_unit, vunit, quantity,
                  math.sqrt(om2c) if om2c > 0 else float("nan"), gamma, info)  # fmt: skip


def write_csv(r: Record, path) -> None:  # noqa: ANN001
    """A lab's CSV: ``t [unit],signal [unit]``; dropped samples as ``NaN``."""
    digits = 9 if r.time_unit == "s" else 6
    with open(path, "w") as fh:
        fh.write(f"t [{r.time_unit}],signal [{r.value_unit}]\n")
        for ti, yi in zip(r.t, r.y, strict=True):
            fh.write(f"{ti:.{digits}f},{'NaN' if not np.isfinite(yi) else repr(float(yi))}\n")


def with_seed(rec: Recording, seed: int) -> Recording:
    return replace(rec, seed=seed)


def sample_jitter(rec: Recording, n: int) -> np.ndarray:
    """The logger's sampling-instant errors (s): zero unless ``rec.jitter_s``; drawn from their
    own stream so that the other impairments' draws do not change."""
    if rec.jitter_s <= 0:
        return np.zeros(n)
    return rec.jitter_s * np.random.default_rng([rec.seed, 7919]).standard_normal(n)


def finish(y: np.ndarray, t: np.ndarray, static_mm: float, rec: Recording,
           rng: np.random.Generator, deg_per_mm: float = 1.0, adc_range: float | None = None,
           ) -> tuple[np.ndarray, str, str, float]:  # fmt: skip
    """The sensor's output ``y`` (mm, mm/s or mm/s^2 about the equilibrium, sampled at the
    instants ``t``, s) as the file holds it: the static level (a laser), the file's unit, hum,
    noise, offset, an offset step, the ADC and dropped samples. ``(values, value_unit, quantity,
    dynamic peak)``."""
    n = len(y)
    if rec.sensor == "laser" and not rec.highpass_hz:  # AC coupling blocks the static level
        y = y + static_mm
    vals, vunit, quantity = _to_unit(y, rec, deg_per_mm)
    dyn = vals - (vals[0] if rec.start == "pretrigger" else float(np.median(vals)))
    peak = float(np.max(np.abs(dyn))) or 1.0
    if rec.hum_rel > 0:
        ph = rng.uniform(0, 2 * math.pi, 1 + len(rec.harmonics))
        amps = (1.0,) + tuple(rec.harmonics)
        for j, (a, p) in enumerate(zip(amps, ph, strict=True)):
            vals = vals + rec.hum_rel * peak * a * np.sin(2 * math.pi * rec.mains_hz * (j + 1) * t
                                                          + p)  # fmt: skip
    if rec.snr_db is not None:
        sd = peak / math.sqrt(2.0 * 10 ** (rec.snr_db / 10.0))
        vals = vals + sd * rng.standard_normal(n)
    vals = vals + rec.offset
    if rec.offset_step is not None:
        frac, rel = rec.offset_step
        vals = vals + np.where(t >= frac * rec.duration_s, rel * peak, 0.0)
    bits = rec.adc_bits
    if bits is not None:
        full = adc_range or rec.adc_range or 1.25 * float(np.max(np.abs(vals)))
        lsb = 2 * full / 2**bits
        vals = np.clip(np.round(vals / lsb) * lsb, -full, full - lsb)
    if rec.nan_gaps:
        for _ in range(rec.nan_gaps):
            i = int(rng.integers(n // 5, n - 10))
            vals[i : i + int(rng.integers(1, 4))] = np.nan
    return vals, vunit, quantity, peak
