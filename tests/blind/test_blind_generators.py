"""The blind generators' own truths: closed forms against root finding, the recorder's exact
responses against an ODE integration that converges to them, the lab's plans as they say.

Fast (a few seconds): the default suite runs them.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, optimize

sys.path.insert(0, str(Path(__file__).parent))

import _blind_recorder as R  # noqa: E402
import _blind_structures as B  # noqa: E402
import _blind_sweeps as S  # noqa: E402

# -- structures ------------------------------------------------------------------------------


@pytest.mark.parametrize("ke2", [50.0, 80.0])
def test_arch_bifurcation_closed_form_is_where_the_antisymmetric_stiffness_vanishes(ke2: float):
    a = B.Arch(e=math.sqrt(ke2))
    q1b, pb = a.bifurcation()
    # second method: Brent on V22 along the symmetric path parametrised by q1
    q1 = B._brent(lambda q: a.hessian(q, 0.0)[1, 1], q1b * 0.5, a.e)
    assert q1 == pytest.approx(q1b, rel=1e-13, abs=1e-13)
    assert a.load_on_symmetric_path(q1) == pytest.approx(pb, rel=1e-12)
    assert a.kind() == "subcritical-pitchfork"
    # subcritical: on the bifurcated path (V2 = 0 with q2 != 0: s fixed) the load falls as q2
    # grows
    for q2 in (1e-3, 1e-2, 1e-1):
        q1p = math.sqrt(q1b**2 - a.alpha * q2**2)
        p = -((q1p - a.e) + a.kappa / 8 * a.s(q1p, q2) * q1p)
        assert np.allclose(a.gradient(q1p, q2, p), 0.0, atol=1e-12)
        assert p < pb


def test_arch_limit_point_closed_form_is_the_maximum_load_of_the_symmetric_path():
    a = B.Arch(e=math.sqrt(30.0))
    q1l, pl = a.limit_point()
    res = optimize.minimize_scalar(lambda q: -a.load_on_symmetric_path(q), bounds=(0.5, a.e),
                                   method="bounded", options={"xatol": 1e-12})  # fmt: skip
    assert -res.fun == pytest.approx(pl, rel=1e-13)
    assert res.x == pytest.approx(q1l, rel=1e-6)  # a maximum is flat: its place to sqrt(eps)
    assert a.hessian(q1l, 0.0)[0, 0] == pytest.approx(0.0, abs=1e-13)
    assert a.kind() == "saddle-node"


@pytest.mark.parametrize("e2", [0.01, -0.05, 0.2])
def test_imperfect_arch_fold_two_methods_agree(e2: float):
    a = B.Arch(e=math.sqrt(80.0), e2=e2)
    pf = a.critical_load()
    assert a.fold_by_maximum() == pytest.approx(pf, rel=1e-12)
    assert pf < a.__class__(e=a.e).critical_load()  # an imperfection lowers the load
    q2 = a._q2_fold()
    q1 = a._q1_of_q2(q2)
    assert np.allclose(a.gradient(q1, q2, pf), 0.0, atol=1e-11)
    assert abs(np.linalg.det(a.hessian(q1, q2))) < 1e-10


def test_imperfect_arch_fold_converges_to_the_bifurcation_by_koiters_two_thirds_law():
    perfect = B.Arch(e=math.sqrt(80.0))
    pb = perfect.critical_load()
    ratios = []
    for e2 in (1e-3, 1e-4, 1e-5, 1e-6):
        pf = B.Arch(e=perfect.e, e2=e2).critical_load()
        ratios.append((pb - pf) / e2 ** (2 / 3))
    # the coefficient converges (differences shrink like e2^(1/3))
    d = np.abs(np.diff(ratios))
    assert np.all(d[1:] < d[:-1])
    assert d[-1] / ratios[-1] < 2e-2


@pytest.mark.parametrize("frac", [0.0, 0.3, 0.8, 0.999])
@pytest.mark.parametrize("e2", [0.0, 0.05])
def test_arch_states_are_equilibria_and_the_hessian_is_the_gradients_derivative(frac, e2):
    a = B.Arch(e=math.sqrt(50.0), e2=e2)
    p = frac * a.critical_load()
    q1, q2 = a.equilibrium(p)
    assert np.allclose(a.gradient(q1, q2, p), 0.0, atol=1e-11)
    h = 1e-6
    num = np.column_stack([(a.gradient(q1 + h, q2, p) - a.gradient(q1 - h, q2, p)) / (2 * h),
                           (a.gradient(q1, q2 + h, p) - a.gradient(q1, q2 - h, p)) / (2 * h)])
    assert np.allclose(num, a.hessian(q1, q2), rtol=1e-8, atol=1e-8)
    st = a.state(p)
    assert np.all(st.omega2 > 0)


def test_arch_crossing_the_critical_mode_is_not_the_lowest_line_far_from_mu_star():
    a = B.Arch(e=math.sqrt(50.0))
    far, near = a.state(0.0), a.state(0.99 * a.critical_load())
    assert far.critical == 1 and near.critical == 0  # the antisymmetric mode crosses below
    assert a.state(a.critical_load() * (1 - 1e-9)).omega2[0] < 1e-7


def test_arch_remote_branch_is_a_stable_equilibrium_beyond_the_snap():
    a = B.Arch(e=math.sqrt(30.0))
    p = 1.05 * a.critical_load()
    q1, q2 = a.remote_equilibrium(p)
    assert q1 < 0
    assert np.allclose(a.gradient(q1, q2, p), 0.0, atol=1e-11)
    assert np.all(np.linalg.eigvalsh(a.hessian(q1, q2)) > 0)


def test_foundation_column_buckles_in_its_second_mode_while_the_first_is_the_lowest_line():
    c = B.FoundationColumn(beta=10.0)
    assert c.critical_mode() == 2 and c.critical_load() == 6.5  # 4 + 10/4
    assert c.critical_load_by_root() == pytest.approx(6.5, rel=1e-13)
    st = c.state(0.0)
    assert st.critical == 1  # not the lowest line at p = 0
    assert st.omega2[c.state(0).critical] == 26.0


def test_three_link_buckling_loads_closed_form_against_the_determinant():
    for k2, m2 in ((1.0, 1.0), (1.3, 2.0), (0.7, 0.5)):
        c = B.ThreeLinkColumn(k2=k2, m2=m2)
        p1, p2 = c.buckling_loads()
        assert c.critical_load_by_root() == pytest.approx(p1, rel=1e-13)
        for p in (p1, p2):
            assert abs(np.linalg.det(c.k() - p * c.g())) < 1e-12 * np.abs(c.k()).max() ** 2
        # frequencies: det(K - P G - w^2 M) = 0 at each eigenvalue
        for p in (0.0, 0.5 * p1, 0.99 * p1):
            st = c.state(p)
            for w2 in st.omega2:
                d = np.linalg.det(c.k() - p * c.g() - w2 * np.diag([c.m1, c.m2]))
                assert abs(d) < 1e-10
    assert B.ThreeLinkColumn().buckling_loads() == pytest.approx((1.0, 3.0), rel=1e-14)


# -- recorder --------------------------------------------------------------------------------


def _ode_output(om2: float, gam: float, rec: R.Recording, t: np.ndarray, rtol: float):
    """The same mode and sensor by numerical integration (state space, solve_ivp)."""
    a, b = 1.0 / rec.tau_decay_s, 1.0 / rec.tau_rise_s
    wg = 2 * math.pi * rec.geophone_hz
    zg = rec.geophone_zeta

    def force(s: float) -> float:
        f = (math.exp(-a * s) - math.exp(-b * s)) if s >= 0 else 0.0
        if rec.second_hit is not None and s >= rec.second_hit[0]:
            u = s - rec.second_hit[0]
            f += rec.second_hit[1] * (math.exp(-a * u) - math.exp(-b * u))
        return f

    def rhs(s, z):  # noqa: ANN001, ANN202
        x, v, g, gd = z
        acc = force(s) - 2 * gam * v - om2 * x
        # geophone: g'' + 2 zg wg g' + wg^2 g = v''  (output g, the filtered velocity)
        # written with h = g - v:  h'' + 2 zg wg h' + wg^2 h = -2 zg wg v' - wg^2 v
        gdd = -2 * zg * wg * gd - wg * wg * g - 2 * zg * wg * acc - wg * wg * v
        return [v, acc, gd, gdd]

    sol = integrate.solve_ivp(rhs, (0.0, t[-1]), [0.0, 0.0, 0.0, 0.0], t_eval=t, rtol=rtol,
                              atol=rtol * 1e-6, method="DOP853",
                              max_step=min(rec.tau_rise_s, 2e-3))  # fmt: skip
    x, v, h, _ = sol.y
    acc = np.array([rhs(s, z)[1] for s, z in zip(t, sol.y.T, strict=True)])
    return {"laser": x, "accel": acc, "geophone": h + v}[rec.sensor]


_CASES = [(s, om2, gam) for s in ("laser", "accel", "geophone")
          for om2, gam in ((2500.0, 1.0), (30.0, 8.0))]  # ringing; overdamped


@pytest.mark.parametrize("sensor,om2,gam", [
    c if c == ("geophone", 2500.0, 1.0) else pytest.param(*c, marks=pytest.mark.slow)
    for c in _CASES])  # fmt: skip
def test_residue_response_matches_an_ode_integration_that_converges_to_it(sensor, om2, gam):
    rec = R.Recording(sensor=sensor, tau_decay_s=4e-3, tau_rise_s=4e-4, second_hit=(0.13, 0.4))
    t = np.linspace(0.0, 0.5, 401)
    exact = R.mode_output(t, om2, gam, 1.0, rec)
    scale = np.max(np.abs(exact))
    errs = [np.max(np.abs(_ode_output(om2, gam, rec, t, rtol) - exact)) / scale
            for rtol in (1e-5, 1e-11)]  # fmt: skip
    assert errs[-1] < 1e-8
    assert errs[-1] < errs[0]


def test_free_ring_down_has_the_modes_rate_and_decay():
    rec = R.Recording(tau_decay_s=1e-3, tau_rise_s=1e-4)
    om2, gam = (2 * math.pi * 7.0) ** 2, 0.9
    t = np.linspace(0.05, 3.0, 6000)
    y = R.mode_output(t, om2, gam, 1.0, rec)
    wd = math.sqrt(om2 - gam * gam)

    def model(p):  # noqa: ANN001, ANN202
        amp, ph, w, g = p
        return amp * np.exp(-g * t) * np.cos(w * t + ph)

    p0 = [np.max(np.abs(y)), 0.0, wd * 1.001, gam * 1.1]
    best = None
    for ph0 in np.linspace(-3, 3, 7):
        p0[1] = ph0
        r = optimize.least_squares(lambda p: model(p) - y, p0, xtol=1e-15, ftol=1e-15)
        if best is None or r.cost < best.cost:
            best = r
    amp, ph, w, g = best.x
    # after the force decays the record is the free mode alone (force poles at 1e3, 1e4 /s)
    assert w == pytest.approx(wd, rel=1e-9)
    assert g == pytest.approx(gam, rel=1e-7)


@pytest.mark.parametrize("order", [1, 2])
def test_ac_coupling_is_the_high_pass_ode_applied_to_the_sensors_output(order: int):
    """``highpass_hz``: the residues of ``s^order / (s + wc)^order`` times the laser's output equal
    the filter's ODE ``z_k' = z_{k-1}' - wc z_k`` integrated beside the mode (``z_0 = x``)."""
    rec = R.Recording(tau_decay_s=4e-3, tau_rise_s=4e-4, highpass_hz=1.5, highpass_order=order)
    om2, gam, wc = (2 * math.pi * 2.0) ** 2, 0.3, 2 * math.pi * 1.5
    a, b = 1.0 / rec.tau_decay_s, 1.0 / rec.tau_rise_s
    t = np.linspace(0.0, 3.0, 601)
    exact = R.mode_output(t, om2, gam, 1.0, rec)

    def rhs(s, z):  # noqa: ANN001, ANN202
        x, v, *h = z
        acc = (math.exp(-a * s) - math.exp(-b * s)) - 2 * gam * v - om2 * x
        d = [v]
        for hk in h:  # each stage: its input's derivative minus wc times itself
            d.append(d[-1] - wc * hk)
        return [v, acc, *d[1:]]

    sol = integrate.solve_ivp(rhs, (0.0, t[-1]), [0.0] * (2 + order), t_eval=t, rtol=1e-11,
                              atol=1e-17, method="DOP853", max_step=rec.tau_rise_s)  # fmt: skip
    assert np.max(np.abs(sol.y[-1] - exact)) < 1e-7 * np.max(np.abs(exact))
    # a laser behind AC coupling has no static level: at rest before the hit it reads 0
    st = B.Arch(e=math.sqrt(30.0)).state(2.0)
    assert abs(st.static) > 0.1
    rec = R.Recording(rate_hz=500.0, duration_s=2.0, snr_db=None)
    dc = R.record(st, 2 * math.pi * 3.0, 0.5, rec, 1e4)
    ac = R.record(st, 2 * math.pi * 3.0, 0.5, replace(rec, highpass_hz=0.5), 1e4)
    assert dc.y[0] == pytest.approx(st.static) and ac.y[0] == 0.0


def test_record_impairments_are_what_they_say():
    st = B.FoundationColumn().state(3.0)
    rec = R.Recording(rate_hz=500.0, duration_s=2.0, hum_rel=0.05, snr_db=None, adc_bits=12,
                      nan_gaps=2, unit="in", seed=3)  # fmt: skip
    r = R.record(st, 2 * math.pi * 3.0, 0.5, rec, 1e4)
    assert r.value_unit == "in" and r.quantity == "displacement"
    assert 2 <= int(np.isnan(r.y).sum()) <= 6
    y = r.y[np.isfinite(r.y)]
    levels = np.unique(np.round(np.diff(np.unique(y)) / np.min(np.diff(np.unique(y)))))
    assert levels[0] == 1.0  # on the ADC's grid
    assert len(np.unique(y)) <= 2**12
    g = R.record(st, 2 * math.pi * 3.0, 0.5, R.Recording(sensor="geophone", unit="V"), 1e4)
    assert g.quantity == "velocity" and g.value_unit == "V"


# -- plans -----------------------------------------------------------------------------------


@pytest.mark.parametrize("family", S.FAMILIES)
def test_plans_stop_where_they_say(family: str, tmp_path: Path):
    far = S.campaign(family, "far", 0)
    assert far.t_ratio(max(far.controls)) == pytest.approx(1.6, rel=1e-9)
    lab = S.campaign(family, "lab", 0)
    assert 3.0 <= lab.t_ratio(max(lab.controls)) <= 6.0
    assert len(lab.controls) > len(set(lab.controls))  # a repeated control
    assert max(lab.controls) < lab.mu_star()
    past = S.campaign(family, "past", 0)
    assert past.past and past.past[0] > past.mu_star()


def test_a_campaign_writes_records_a_manifest_and_its_truth(tmp_path: Path):
    camp = S.campaign("arch_fold", "past", 1, duration_s=0.5, rate_hz=500.0)
    truth = camp.write(tmp_path)
    rows = (tmp_path / "manifest.csv").read_text().splitlines()
    assert rows[0] == "path,control" and len(rows) == len(truth.names) + 1
    assert truth.mu_star == pytest.approx(camp.mu_star() * camp.load_scale, rel=1e-15)
    assert list(truth.untrusted.values()) == ["remote branch"]
    assert all((tmp_path / n).exists() for n in truth.names)
    head = (tmp_path / truth.names[0]).read_text().splitlines()[0]
    assert head == "t [s],signal [in]"
    assert truth.sigma2[-1] < 0  # the remote branch is stable
