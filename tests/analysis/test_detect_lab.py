"""The detector on records made the way labs make them (tests/labrec's independent generator).

Each impairment alone (pre-trigger with hum, repeated kicks, clipping, drift, a sensor that is
not a displacement), the user's options (quantity, start, notch) and the acceptance figures of
issue 27: over random lab records with every impairment on, the fundamental within 1 % in
>= 95 % and wrong without a warning in <= 1 % (slow: 300 records; a fast sample by default).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "labrec"))
import labgen  # noqa: E402

from service.analysis.detect import (  # noqa: E402
    FLAG_CODES,
    WARNING_FLAGS,
    Mode,
    _aside,  # noqa: E402
    detect,
)
from service.analysis.detect._modes import _fundamental  # noqa: E402
from service.analysis.errors import ParameterError  # noqa: E402
from service.recordings import quantity_of  # noqa: E402

OFF = {k: False for k in labgen.IMPAIRMENTS}
#: A wrong fundamental without one of the detector's WARNING_FLAGS (only flags that describe
#: the record and what was done with it: pretrigger, stationary_line, clipped, drift...) is
#: "silently wrong".


def _record(seed: int, **switches) -> labgen.LabRecord:
    kw = {**OFF, "noise": 40.0, "quantity": "displacement", **switches}
    return labgen.draw_record(np.random.default_rng([27, seed]), **kw)


def _right(det, rec) -> bool:
    f = det.fundamental
    return f is not None and abs(math.sqrt(abs(f.sigma2)) / rec.truth.omega0 - 1) <= 0.01


def test_new_flags_are_documented() -> None:
    import service.analysis.detect as pkg

    for code in ("stationary_line", "drift", "negligible_growth", "forced_part",
                 "repeated_kick", "clipped", "start_given", "no_static_level"):  # fmt: skip
        assert code in FLAG_CODES
        assert f"``{code}``" in pkg.__doc__, code


@pytest.mark.parametrize("quantity", ["velocity", "acceleration"])
def test_poles_from_any_sensor_the_static_level_only_from_a_displacement(quantity: str) -> None:
    rec = _record(1, quantity=quantity)
    det = detect(rec.y, dt=rec.dt, quantity=quantity)
    assert _right(det, rec)
    assert math.isnan(det.static_level) and "no_static_level" in det.flag_codes
    assert det.quantity == quantity
    disp = _record(1, quantity="displacement")
    ref = detect(disp.y, dt=disp.dt, quantity="displacement")
    assert math.isfinite(ref.static_level) and "no_static_level" not in ref.flag_codes
    # the default reads the record as a displacement, as before
    assert detect(rec.y, dt=rec.dt).quantity == "displacement"


@pytest.mark.parametrize(
    ("kwargs", "param"),
    [({"quantity": "strain"}, "quantity"), ({"start": -1.0}, "start"), ({"start": 1e9}, "start"),
     ({"notch": [0.0]}, "notch"), ({"notch": [1e6]}, "notch"), ({"notch": "fifty"}, "notch")],
)  # fmt: skip
def test_lab_options_are_validated_by_name(kwargs: dict, param: str) -> None:
    rec = _record(2)
    with pytest.raises(ParameterError) as ei:
        detect(rec.y, dt=rec.dt, **kwargs)
    assert ei.value.parameter == param


@pytest.mark.parametrize("seed", [3, 4])
def test_hum_over_a_pre_trigger_is_a_line_and_the_kick_is_found(seed: int) -> None:
    """Hum at 8 % of the peak (and its harmonics) over a 20 % pre-trigger: the cut lies at the
    kick (not at sample 0: the issue's failure), the lines are fitted and set aside."""
    rec = _record(seed, pretrigger=0.2, hum=0.08)
    det = detect(rec.y, dt=rec.dt)
    assert _right(det, rec)
    k = rec.kick_index
    contact = int(rec.lab.pulse_s / rec.dt)
    assert k - 2 <= det.start <= k + contact + rec.y.size // 20, (det.start, k)
    assert {"pretrigger", "stationary_line"} <= set(det.flag_codes)
    lines = [m for m in det.modes if m.kind == "line"]
    mains = [f for f, _ in labgen.hum_lines(rec.lab)]
    assert lines and all(min(abs(m.frequency / f - 1) for f in mains) < 2e-3 for m in lines)
    assert det.fundamental.mode.kind == "mode"


def test_a_second_kick_ends_the_window() -> None:
    rec = _record(5, repeats=1)
    det = detect(rec.y, dt=rec.dt)
    assert _right(det, rec) and "repeated_kick" in det.flag_codes
    later = int(rec.lab.kicks[0][0] * rec.lab.duration / rec.dt)
    assert det.start + det.n_samples <= later + 2


def test_clipped_samples_are_read_as_censored() -> None:
    rec = _record(6, clipping=0.7)
    det = detect(rec.y, dt=rec.dt)
    assert _right(det, rec) and "clipped" in det.flag_codes
    # the window runs through the clipped runs (censored, not cut around)
    inside = int(rec.clipped[det.start : det.start + det.n_samples].sum())
    assert inside > 0
    msg = next(f.message for f in det.flags if f.code == "clipped")
    assert "clipped one(s) among them as censored" in msg


def test_the_expected_value_beyond_an_edge_is_the_truncated_normal_mean() -> None:
    from scipy.stats import truncnorm

    from service.analysis.detect._censored import expected_beyond

    mu = np.array([-30.0, -3.0, -0.5, 0.0, 0.7, 4.0, 40.0])
    s, edge = 0.8, 1.0
    up = truncnorm.mean((edge - mu) / s, np.inf, loc=mu, scale=s)
    down = truncnorm.mean(-np.inf, (edge - mu) / s, loc=mu, scale=s)
    assert np.allclose(expected_beyond(mu, edge, s, True), up, rtol=1e-9, atol=1e-12)
    assert np.allclose(expected_beyond(mu, edge, s, False), down, rtol=1e-9, atol=1e-12)


def test_a_heavily_clipped_ring_down_is_fitted_through_its_clipped_peaks() -> None:
    """A damped sine clipped at 55 % of its peak on both sides from the kick on (every early
    peak flat) after a quiet lead-in: the censored (EM) fit finds its rate and its amplitude,
    which the clipped values alone would put at the clip level."""
    rng = np.random.default_rng(11)
    fs, f0, g, n = 1000.0, 6.0, 0.4, 6000
    t = np.arange(n) / fs
    k0 = 600
    u = np.clip(t - t[k0], 0.0, None)
    x = np.where(t >= t[k0], np.exp(-g * u) * np.sin(2 * math.pi * f0 * u), 0.0)
    y = x + 2e-3 * rng.standard_normal(n)
    edge = 0.55
    y = np.clip(y, -edge, edge)
    det = detect(y, dt=1 / fs)
    assert "clipped" in det.flag_codes
    f = det.fundamental
    w0 = math.hypot(2 * math.pi * f0, g)
    assert math.sqrt(abs(f.sigma2)) == pytest.approx(w0, rel=1e-3)
    assert f.damping == pytest.approx(g, rel=0.05)
    # the amplitude at the kick (1.0) from the window's first sample
    a_kick = f.mode.amplitude * math.exp(f.damping * (det.start - k0) / fs)
    assert a_kick == pytest.approx(1.0, rel=0.05)


@pytest.mark.parametrize("seed", [7, 8, 9])
def test_a_drift_is_never_the_fundamental(seed: int) -> None:
    rec = _record(seed, drift=True)
    det = detect(rec.y, dt=rec.dt)
    assert _right(det, rec), [(m.kind, math.sqrt(abs(m.sigma2))) for m in det.modes]


def test_the_users_notch_and_start() -> None:
    """A line below the fundamental (a slow stationary wobble at 0.4 of its frequency) in a
    record with no pre-trigger: given as a notch it is a line, and the fundamental is the
    kicked mode; a start given is used as it is."""
    rec = _record(10, pretrigger=0.1)
    f_line = 0.4 * rec.modes.f0_hz[0]
    y = rec.y[rec.kick_index :] + 0.2 * np.max(np.abs(rec.y)) * np.sin(
        2 * math.pi * f_line * rec.t[: rec.y.size - rec.kick_index] + 0.3
    )
    det = detect(y, dt=rec.dt, notch=[f_line])
    assert _right(det, rec)
    assert any(m.kind == "line" and abs(m.frequency / f_line - 1) < 1e-3 for m in det.modes)
    t0 = (rec.kick_index + 40) * rec.dt
    det = detect(rec.y, dt=rec.dt, start=t0)
    assert det.start == rec.kick_index + 40 and "start_given" in det.flag_codes
    assert _right(det, rec)


def test_a_tiny_growing_component_beside_a_loud_ringing_is_not_an_instability() -> None:
    ring = Mode(40.0, 40.0 / (2 * math.pi), 0.5, -1600.25, 0.3, 0.0, 1e-4, 1e-4, 1e-3)
    tiny = Mode(0.0, 0.0, -0.1, 1e-4, 5e-10, 0.0, 0.0, 1e-3, 1e-5, regime="overdamped",
                real_poles=(0.3, -0.1), real_amplitudes=(5e-10, 0.0))  # fmt: skip
    assert _aside.negligible_growth([ring, tiny], 10.0) == frozenset({1})
    big = Mode(0.0, 0.0, -0.1, 1e-4, 0.05, 0.0, 0.0, 1e-3, 1e-5, regime="overdamped",
               real_poles=(0.3, -0.1), real_amplitudes=(0.05, 0.0))  # fmt: skip
    assert _aside.negligible_growth([ring, big], 10.0) == frozenset()


def _line(f: float, a: float, g: float = 1.5, g_std: float = 0.1, w_std: float = 0.02) -> Mode:
    w = 2 * math.pi * f
    return Mode(w, f, g, -(w * w + g * g), a, 0.0, w_std, g_std, 2 * w * w_std, 0.1 * a)


def test_the_sidebands_of_a_friction_ring_down_are_never_the_fundamental() -> None:
    """The blind friction truss (tests/blind truss_friction lab 0 and 1, first records): the
    fit spreads the linearly decaying ring-down into a comb; its slowest line (1.7 % of the
    dominant's amplitude) was the fundamental, sigma^2 low by 20 %."""
    comb = [_line(6.83663, 0.00802), _line(7.2588, 0.11744), _line(7.60747, 0.46959),
            _line(7.96448, 0.10971), _line(8.32324, 0.00977)]  # fmt: skip
    side, bound = _aside.sidebands(comb, 4.731, frozenset())
    assert side == {0: (2, -2), 1: (2, -1), 3: (2, 1), 4: (2, 2)} and bound is None
    modes, order = _fundamental(comb, n=9462, dt=5e-4, sidebands=side)
    assert order[0] == 2 and modes[1].combination is not None
    # a main lobe split in two (lab 1, mu 0: 8.195 Hz read as 7.999 and 8.416): the carrier
    # lies between them, the dominant's sigma^2 error covers half their difference
    split = [_line(6.965, 0.003684), _line(7.5067, 0.04035), _line(7.9987, 0.3482),
             _line(8.4164, 0.282), _line(8.8825, 0.01922)]  # fmt: skip
    side, bound = _aside.sidebands(split, 4.39, frozenset())
    assert side[3] == (2, 0) and set(side) == {0, 1, 3, 4} and bound == 3
    f = _aside.comb_bounded(split[2], split[3])
    assert f.sigma2_std == pytest.approx(0.5 * abs(split[2].sigma2 - split[3].sigma2))
    assert abs(f.sigma2 + (2 * math.pi * 8.195268782902753) ** 2) < 1.0 * f.sigma2_std
    # two modes and a third that is not at the mirrored frequency: no comb
    assert _aside.sidebands([_line(5.0, 0.1), _line(8.0, 1.0), _line(12.0, 0.1)], 4.0,
                            frozenset()) == ({}, None)  # fmt: skip
    # the loudest term a heavily damped one (the hammer's contact, seed 2702 #38): no comb
    contact = [_line(5.7903, 6.14, 0.0714), _line(9.7425, 9.80, 47.99, 2.0),
               _line(11.3852, 1.42, 3.65), _line(15.7228, 1.26, 3.70)]  # fmt: skip
    assert _aside.sidebands(contact, 6.0, frozenset()) == ({}, None)


def test_a_weak_fundamental_beside_a_much_stronger_close_line_carries_their_difference() -> None:
    """The blind friction truss far 0, last record (truth 9.049 Hz): a weak 8.42 Hz line
    (sigma^2 -2802 +- 18.9, z +22.7) beside a 23x stronger 9.52 Hz one."""
    lines = [_line(8.4185, 0.09), _line(8.9784, 0.588), _line(9.5187, 2.075)]
    assert _aside.split_rival(lines, 0, {1, 2}) == 2
    f = _aside.comb_bounded(lines[0], lines[2])
    assert abs(f.sigma2 + (2 * math.pi * 9.0491423709298) ** 2) < 2.0 * f.sigma2_std
    # a fundamental as strong as its close neighbour keeps its own error
    assert _aside.split_rival([_line(8.4185, 1.0), _line(9.5187, 2.075)], 0, {1}) is None


def test_a_quiet_line_far_below_a_loud_ringing_mode_is_not_the_fundamental() -> None:
    """The unit-less subcritical lab of tests/live (record 17, sampled at 59.79 Hz): the 60 Hz
    hum aliased to 0.205 Hz, its decay 0.0196 +- 0.0165 over 30 s beside the kicked mode (0.918
    Hz, 190x stronger, 9 e-folds) was the fundamental (sigma^2 -1.66 for -33.41)."""
    hum = _line(0.20532, 0.01272, 0.01959, 0.0165)
    ring = _line(0.91822, 2.403, 0.2995, 0.00146)
    assert _aside.quiet_lines([hum, ring], 30.0, frozenset()) == {0}
    # a weak slow mode that decays measurably is a mode
    assert _aside.quiet_lines([_line(0.20532, 0.01272, 0.05, 0.005), ring], 30.0,
                              frozenset()) == frozenset()  # fmt: skip
    # ... and so is a quiet one beside a ringing mode less than 10x stronger
    assert _aside.quiet_lines([_line(0.20532, 0.3, 0.01959, 0.0165), ring], 30.0,
                              frozenset()) == frozenset()  # fmt: skip
    # ... and a fundamental too short-lived in its window to show its decay beside the
    # hammer's contact (seed 2702 #103: 3.7 cycles, decay 0.036 +- 0.737; the contact 164 Hz,
    # decay 414)
    assert _aside.quiet_lines([_line(5.7373, 0.0526, 0.036, 0.737),
                               _line(164.0, 1.151, 414.5, 50.0)], 0.6368,
                              frozenset()) == frozenset()  # fmt: skip


def test_a_slower_component_the_fit_cannot_tell_from_nothing_is_not_the_fundamental() -> None:
    """The blind arch_fold past 2 record at 114.207 N (3.62 s window, Gauss-Newton errors):
    two slow, heavily damped terms the fit made of the noise (0.58 Hz, amplitude 0.0111 +-
    0.0178; 0.78 Hz, 0.0067 +- 0.0235) beside the critical mode it shows (1.886 Hz, 0.0208 +-
    0.0003, sigma^2 -141.5 for the exact -142.5): the slowest was the fundamental (-16.5)."""
    def mode(f: float, g: float, gs: float, a: float, a_s: float) -> Mode:
        w = 2 * math.pi * f
        return Mode(w, f, g, -(w * w + g * g), a, 0.0, 0.01, gs, 1.0, a_s)

    modes = [mode(0.5844, 1.751, 0.79, 0.0111, 0.0178), mode(0.7771, 1.587, 1.66, 0.0067, 0.0235),
             mode(1.8862, 1.039, 0.0146, 0.0208, 0.00029),
             mode(4.583, 0.994, 0.0126, 0.0121, 1.2e-4)]
    assert _aside.undetermined(modes, 3.62, frozenset()) == {0, 1}
    # the same slow terms with their amplitudes determined stay candidates
    sure = [mode(0.5844, 1.751, 0.79, 0.0111, 0.002), *modes[1:]]
    assert _aside.undetermined(sure, 3.62, frozenset()) == {1}
    # no ringing mode the record shows beside them: nothing is set aside
    assert _aside.undetermined(modes[:2], 3.62, frozenset()) == frozenset()


@pytest.mark.parametrize(
    ("unit", "quantity"),
    [("mm", "displacement"), ("um", "displacement"), ("mm/s", "velocity"), ("m/s", "velocity"),
     ("m/s2", "acceleration"), ("m/s^2", "acceleration"), ("g", "acceleration"), ("V", None),
     (None, None)],
)  # fmt: skip
def test_the_quantity_a_unit_measures(unit: str | None, quantity: str | None) -> None:
    assert quantity_of(unit) == quantity


def _campaign(n: int, seed: int, z: list | None = None) -> tuple[int, int, list]:
    """(right, silent wrong, the wrong ones) over ``n`` random records, every impairment on;
    ``z`` (when given) gets the right ones' standardised sigma^2 errors."""
    right = silent = 0
    wrong = []
    for i in range(n):
        rec = labgen.draw_record(np.random.default_rng([seed, i]),
                                 **{k: True for k in labgen.IMPAIRMENTS})  # fmt: skip
        det = detect(rec.y, dt=rec.dt, quantity=rec.quantity)
        if _right(det, rec):
            right += 1
            if z is not None:
                f = det.fundamental
                z.append((f.sigma2 + rec.truth.omega0**2) / f.sigma2_std)
            continue
        warned = [c for c in det.flag_codes if c in WARNING_FLAGS]
        silent += not warned
        wrong.append((i, det.fundamental and math.sqrt(abs(det.fundamental.sigma2)),
                      rec.truth.omega0, det.flag_codes))  # fmt: skip
    return right, silent, wrong


def test_a_fast_sample_of_lab_records_with_every_impairment() -> None:
    right, silent, wrong = _campaign(12, 2701)
    assert right >= 10 and silent == 0, wrong


@pytest.mark.slow
def test_300_lab_records_fundamental_right_in_95_percent_silent_wrong_below_1_percent() -> None:
    """Issue 27's acceptance (seed 2702, quantity given): measured 289/300 right (96.3 %; 286
    before session 19's rules), 0 silent; and the reported sigma^2 errors are honest: the right
    ones' standardised errors ``(sigma2 - truth) / sigma2_std`` lie within 1.96 in >= 90 %
    (measured 94.1 %; 83.5 % with the Gauss-Newton errors alone)."""
    n = 300
    z: list[float] = []
    right, silent, wrong = _campaign(n, 2702, z)
    assert right >= 0.95 * n and silent <= 0.01 * n, (right, silent, wrong)
    assert np.mean(np.abs(z) < 1.96) >= 0.90, np.percentile(np.abs(z), [50, 90, 95, 99])


def _ring(rng: np.random.Generator, phi: float, n: int = 3000) -> tuple[np.ndarray, float]:
    """A damped sine (6 Hz, 1 kHz) kicked after a quiet 20 % lead-in, plus AR(1) noise of
    coefficient ``phi`` (white when 0) at 1 % of the peak; and its true ``sigma^2``."""
    fs, f0, g = 1000.0, 6.0, 0.5
    t = np.arange(n) / fs
    k0 = n // 5
    u = np.clip(t - t[k0], 0.0, None)
    x = np.where(t >= t[k0], np.exp(-g * u) * np.sin(2 * math.pi * f0 * u), 0.0)
    e = rng.standard_normal(n) * 0.01 * math.sqrt(1 - phi * phi)
    for i in range(1, n):
        e[i] += phi * e[i - 1]
    return x + e, -((2 * math.pi * f0) ** 2 + g * g)


def test_the_sandwich_keeps_the_fits_errors_on_white_noise() -> None:
    """White noise: the sandwich's factor stays near 1 (the errors were right already)."""
    from service.analysis.detect import _uncertainty

    y, _ = _ring(np.random.default_rng(5), 0.0)
    det = detect(y, dt=1e-3)
    assert "pretrigger" in det.flag_codes
    orig = _uncertainty.inflation
    try:
        _uncertainty.inflation = lambda modes, *a, **k: [{} for _ in modes]
        plain = detect(y, dt=1e-3)
    finally:
        _uncertainty.inflation = orig
    ratio = det.fundamental.sigma2_std / plain.fundamental.sigma2_std
    assert 1.0 <= ratio < 1.3, ratio


@pytest.mark.parametrize("phi", [0.0, 0.9])
def test_the_sandwich_is_the_scatter_of_least_squares_estimates(phi: float) -> None:
    """Monte Carlo reference: a ring-down's linearised least-squares estimate (amplitude,
    phase, decay rate, frequency, a level and a slope: the exact linear problem, its Jacobian
    written here) from 300 draws of AR(1) noise of coefficient ``phi``. The variance of
    sigma^2's estimate over the draws matches the mean of the variances the sandwich predicts
    from each draw's residual within 0.75-1.4x (measured: 1.01 white, 1.30 at phi = 0.9: the
    residual the sandwich reads lacks the part of the noise the fit absorbed, ~14 % in std);
    for phi = 0.9 (its spectrum near the line ~10x its mean) the white-noise formula alone is
    18x too small in variance."""
    from service.analysis.detect import _uncertainty

    n, dt, w, g, a = 3000, 1e-3, 2 * math.pi * 6.0, 0.5, 1.0
    m = Mode(w, w / (2 * math.pi), g, -(w * w + g * g), a, 0.3, 1e-4, 1e-4, 1e-3)
    u = np.arange(n) * dt
    env = np.exp(-g * u)
    c, s = env * np.cos(w * u + 0.3), env * np.sin(w * u + 0.3)
    J = np.column_stack((np.ones(n), u, c, -a * s, -a * u * c, -a * u * s))
    grad = np.array([0.0, 0.0, 0.0, 0.0, -2 * g, -2 * w])  # sigma^2 = -(w^2 + g^2)
    JtJi = np.linalg.inv(J.T @ J)
    rng = np.random.default_rng(2027)
    est, pred, white = [], [], []
    for _ in range(300):
        e = rng.standard_normal(n)
        for i in range(1, n):
            e[i] += phi * e[i - 1]
        theta, *_ = np.linalg.lstsq(J, e, rcond=None)
        r = e - J @ theta
        s2 = float(r @ r) / (n - J.shape[1])
        v0 = s2 * float(grad @ JtJi @ grad)
        f = _uncertainty.inflation([m], r, dt, math.sqrt(s2))[0]["sigma2"]
        est.append(float(grad @ theta))
        pred.append(v0 * f * f)
        white.append(v0)
    emp = float(np.var(est))
    assert 0.75 <= emp / float(np.mean(pred)) <= 1.4, (emp, np.mean(pred), np.mean(white))
    if phi:
        assert emp > 4.0 * float(np.mean(white))
