"""The friction truss's truths and the recorder's new impairments (fast; the default suite).

The von Mises truss's limit load in closed form against a bounded maximisation of its load
path, its stiffness against the potential's second difference, its square-root law near the
snap; the joint-friction response (closed form, piecewise) against an event-driven ODE
integration that converges to it; the friction's cycles as defined; the DC offset step and the
sampling jitter of ``_blind_recorder`` as they say; the ``veryfar`` plan.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate

sys.path.insert(0, str(Path(__file__).parent))

import _blind_recorder as R  # noqa: E402
import _blind_sweeps as S  # noqa: E402
import _blind_truss as TR  # noqa: E402


@pytest.mark.parametrize("h0", [0.1, 0.2, 0.3])
def test_truss_limit_load_closed_form_is_the_maximum_of_its_load_path(h0: float):
    tr = TR.FrictionTruss(h0=h0, ea=1e4)
    assert tr.critical_load() == pytest.approx(tr.critical_load_by_maximum(), rel=1e-12)
    hc = tr.h_critical()
    assert abs(tr.stiffness(hc)) < 1e-12 * tr.stiffness(h0)
    assert 0 < hc < h0 and tr.kind() == "saddle-node"


@pytest.mark.parametrize("frac", [0.0, 0.3, 0.9, 0.999])
def test_truss_states_are_equilibria_and_the_stiffness_is_the_potentials_curvature(frac):
    tr = TR.FrictionTruss(h0=0.25, ea=1e4)
    p = frac * tr.critical_load()
    h = tr.equilibrium(p)
    assert tr.load(h) == pytest.approx(p, rel=1e-12, abs=1e-12 * tr.critical_load())
    d = 1e-4 * tr.h0
    v = [tr.potential(h + k * d, p) for k in (-2, -1, 0, 1, 2)]
    # fourth-order central differences: V' = 0 and V'' = stiffness
    v1 = (v[0] - 8 * v[1] + 8 * v[3] - v[4]) / (12 * d)
    v2 = (-v[0] + 16 * v[1] - 30 * v[2] + 16 * v[3] - v[4]) / (12 * d * d)
    scale = tr.ea * tr.h0**2
    assert abs(v1) < 1e-8 * scale
    assert v2 == pytest.approx(tr.stiffness(h), rel=1e-5, abs=1e-7 * tr.stiffness(tr.h0))
    st = tr.state(p)
    assert st.omega2[0] == pytest.approx(tr.stiffness(h) / tr.m, rel=1e-15)
    assert st.static == pytest.approx(tr.h0 - h, abs=1e-15)


def test_truss_stiffness_vanishes_as_the_square_root_of_the_distance_to_the_snap():
    tr = TR.FrictionTruss(h0=0.2, ea=1e4)
    pc = tr.critical_load()
    # V'' ~ sqrt(2 V3 (P_c - P)), V3 = V'''(h_c) in closed form: the saddle-node's law
    hc = tr.h_critical()
    v3 = 6.0 * tr.ea * tr.b**2 * hc / tr.length(hc) ** 5
    ratios = [tr.state(pc * (1 - e)).omega2[0] / math.sqrt(2 * v3 * pc * e)
              for e in (1e-3, 1e-5, 1e-7)]  # fmt: skip
    errs = [abs(r - 1.0) for r in ratios]
    assert errs[2] < 1e-3
    # the first correction is of relative order sqrt(P_c - P): 10x smaller per 100x closer
    assert errs[1] / errs[0] == pytest.approx(0.1, rel=0.1)
    assert errs[2] / errs[1] == pytest.approx(0.1, rel=0.1)


def test_truss_remote_branch_is_a_stable_equilibrium_beyond_the_snap():
    tr = TR.FrictionTruss(h0=0.2, ea=1e4)
    p = 1.3 * tr.critical_load()
    st = tr.state(p, remote=True)
    h = tr.h0 - st.static
    assert h < -tr.h0 and st.omega2[0] > 0 and st.branch == "remote"
    assert tr.load(h) == pytest.approx(p, rel=1e-12)


def _event_ode(t: np.ndarray, w0: float, g: float, v0: float, f: float, rtol: float):
    """The friction oscillator integrated numerically, segment by segment between the zeros
    of the velocity (located as events), sticking where the spring cannot beat friction."""
    out = np.full(t.shape, np.nan)
    t0, z, end = 0.0, np.array([0.0, v0]), float(t[-1])
    while t0 < end:
        if z[1] == 0.0:
            if w0 * w0 * abs(z[0]) <= f:
                out[t >= t0] = z[0]
                break
            sgn = -math.copysign(1.0, z[0])
        else:
            sgn = math.copysign(1.0, z[1])

        def turn(_t, y):  # noqa: ANN001, ANN202
            return y[1]

        turn.terminal, turn.direction = True, -sgn
        r = integrate.solve_ivp(lambda _t, y, s=sgn: [y[1], -2 * g * y[1] - w0 * w0 * y[0] - f * s],
                                (t0, end), z, events=turn, rtol=rtol, atol=rtol * 1e-3,
                                dense_output=True, method="DOP853")  # fmt: skip
        te = float(r.t[-1])
        on = (t >= t0) & (t <= te)
        out[on] = r.sol(t[on])[0]
        if r.status != 1:
            break
        t0, z = float(r.t_events[0][0]), np.array([float(r.y_events[0][0][0]), 0.0])
    return out


@pytest.mark.parametrize("w0,g,v0,f", [(2 * math.pi * 5, 0.3, 10.0, 2.0),  # rings, no stick
                                       (2 * math.pi * 2, 0.2, 5.0, 6.0)])  # sticks early
def test_friction_response_matches_an_event_driven_ode_that_converges_to_it(w0, g, v0, f):
    t = np.linspace(0.0, 3.0, 1501)
    exact = TR.friction_response(t, w0, g, v0, f)
    scale = float(np.max(np.abs(exact)))
    errs = [float(np.nanmax(np.abs(_event_ode(t, w0, g, v0, f, r) - exact))) / scale
            for r in (1e-6, 1e-12)]  # fmt: skip
    assert errs[1] < 1e-9
    assert errs[1] < errs[0]


def test_friction_keeps_the_frequency_and_decays_linearly_to_a_stick():
    w0, v0 = 2 * math.pi * 4.0, 12.0
    n = 12.0  # cycles to sticking (no viscous damping)
    f = v0 * w0 / (4 * n)
    segs = TR.turning_points(w0, 0.0, v0, f, 100.0)
    turns = [s for s in segs[1:] if s[1] != s[2]]
    gaps = np.diff([s[0] for s in turns])
    assert np.allclose(gaps, math.pi / w0, rtol=1e-12)  # the frequency is omega_0 exactly
    amps = np.abs([s[1] for s in turns])
    assert np.allclose(np.diff(amps), -2 * f / w0**2, rtol=1e-9)  # a linear envelope
    assert 2 * n - 2 <= len(turns) <= 2 * n + 2
    stuck = segs[-1]
    assert stuck[1] == stuck[2] and w0 * w0 * abs(stuck[1]) <= f  # at rest off its equilibrium


def test_the_friction_campaign_records_what_it_says(tmp_path: Path):
    camp = S.campaign("truss_friction", "lab", 0, duration_s=1.0)
    camp = replace(camp, controls=camp.controls[:2], adaptive_length=False)
    truth = camp.write(tmp_path)
    v0, f = camp.friction()
    s0 = camp.state(camp.controls[0])
    w0 = math.sqrt(s0.omega2[0]) * camp.omega_scale()
    assert v0 * w0 / (4 * f) == pytest.approx(camp.friction_cycles, rel=1e-12)
    assert truth.kind == "saddle-node" and truth.right == frozenset({"saddle-node"})
    assert truth.sigma2[0] == pytest.approx(-w0 * w0, rel=1e-12)
    y = np.loadtxt(tmp_path / truth.names[0], delimiter=",", skiprows=1)[:, 1]
    assert np.max(np.abs(y - y[0])) == pytest.approx(camp.rec.peak_mm, rel=0.3)


def test_offset_step_and_sampling_jitter_are_what_they_say():
    st = S.campaign("threelink", "lab", 0).state(0.0)
    base = R.Recording(rate_hz=1000.0, duration_s=2.0, snr_db=None, seed=5)
    r0 = R.record(st, 30.0, 0.5, base, 1e4)
    r1 = R.record(st, 30.0, 0.5, replace(base, offset_step=(0.5, 0.2)), 1e4)
    d = r1.y - r0.y
    after = r0.t >= 1.0
    assert np.allclose(d[~after], 0.0, atol=0.0)
    assert np.allclose(d[after], 0.2 * r0.info["peak"], rtol=1e-12)
    j = R.record(st, 30.0, 0.5, replace(base, jitter_s=1e-5), 1e4)
    assert np.array_equal(j.t, r0.t)  # nominal stamps
    dev = np.max(np.abs(j.y - r0.y)) / r0.info["peak"]
    assert 0 < dev < 0.05  # the slope times the jitter
    js = R.record(st, 30.0, 0.5, replace(base, jitter_s=1e-4, jitter_stamped=True), 1e4)
    steps = np.diff(js.t)
    assert np.std(steps) == pytest.approx(math.sqrt(2) * 1e-4, rel=0.1)
    assert np.mean(steps) == pytest.approx(1e-3, rel=1e-3)


@pytest.mark.parametrize("family", ["arch_fold", "threelink", "truss_friction"])
def test_the_veryfar_plan_stops_at_t_ratio_1_3_and_allows_no_type(family: str, tmp_path):
    camp = S.campaign(family, "veryfar", 0, duration_s=0.2, rate_hz=200.0)
    assert camp.t_ratio(max(camp.controls)) == pytest.approx(1.3, rel=1e-9)
    assert 6 <= len(set(camp.controls)) <= 9
    assert max(camp.controls) < camp.mu_star()
