"""reconcile: the fundamental across a sweep, and records set aside with their reason and name."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from service.analysis.common import Flag
from service.analysis.detect import Detection, Fundamental, Mode, detect
from service.analysis.errors import ParameterError
from service.analysis.reconcile import SET_ASIDE, reconcile


def _mode(root: float, gamma: float = 0.05, amp: float = 1.0, sign: float = -1.0) -> Mode:
    s2 = sign * root * root
    om = math.sqrt(max(root * root - gamma * gamma, 0.0)) if sign < 0 else 0.0
    return Mode(om, om / (2 * math.pi), gamma, s2, amp, 0.0, 1e-4, 1e-4, 1e-4 * root,
                1e-3)  # fmt: skip


def _det(*roots: float, signs: tuple[float, ...] | None = None) -> Detection:
    signs = signs or (-1.0,) * len(roots)
    modes = tuple(_mode(r, sign=s) for r, s in zip(roots, signs, strict=True))
    fund = Fundamental(modes[0], 0) if modes else None
    flags = () if modes else (Flag("no_mode", "nothing"),)
    return Detection(modes, fund, 0.1, 1e-3, flags, "varpro", 1e-3, 40.0, 1000, 1e-3)


def _aside(d: Detection) -> list[Flag]:
    return [f for f in d.flags if f.code == SET_ASIDE]


def test_clean_sweep_unchanged():
    dets = [_det(r, 3 * r) for r in (10.0, 9.0, 8.0, 6.0)]
    out = reconcile(dets, np.arange(4.0), names=[f"r{i}.csv" for i in range(4)])
    assert out == tuple(dets)


def test_no_mode_and_growing_set_aside_with_name():
    dets = [_det(10.0), _det(), _det(9.0, signs=(1.0,)), _det(8.0)]
    names = ["a.csv", "b.csv", "c.npz", "d.csv"]
    out = reconcile(dets, np.array([0.0, 1.0, 2.0, 3.0]), names=names)
    assert out[0] == dets[0] and out[3] == dets[3]
    (fb,) = _aside(out[1])
    assert "b.csv" in fb.message and "no mode" in fb.message
    (fc,) = _aside(out[2])
    assert "c.npz" in fc.message and "sigma^2" in fc.message and ">= 0" in fc.message
    # the rest of the detection is kept as it was
    assert out[2].modes == dets[2].modes and out[2].fundamental == dets[2].fundamental


def test_band_moves_the_fundamental_and_sets_aside_outside():
    # a slow drift-like mode at 0.5 below the ringing mode at 10; the band says [5, 20]
    dets = [_det(0.5, 10.0), _det(9.0, 30.0), _det(40.0)]
    out = reconcile(dets, np.arange(3.0), names=["x", "y", "z"], band=(5.0, 20.0))
    assert out[0].fundamental.index == 1
    assert math.isclose(math.sqrt(-out[0].fundamental.sigma2), 10.0)
    assert "fundamental_band" in out[0].flag_codes and not _aside(out[0])
    assert out[1] == dets[1]
    (fz,) = _aside(out[2])
    assert "z" in fz.message and "band" in fz.message


@pytest.mark.parametrize(
    ("kwargs", "param"),
    [
        ({"controls": np.arange(2.0), "names": ["a", "b", "c"]}, "controls"),
        ({"controls": np.array([0.0, np.nan, 1.0]), "names": ["a", "b", "c"]}, "controls"),
        ({"controls": np.arange(3.0), "names": ["a", "b"]}, "names"),
        ({"controls": np.arange(3.0), "names": ["a", "b", "c"], "band": (5.0, 1.0)}, "band"),
        ({"controls": np.arange(3.0), "names": ["a", "b", "c"], "band": "x"}, "band"),
    ],
)
def test_bad_arguments_name_the_field(kwargs, param):
    dets = [_det(1.0)] * 3
    controls = kwargs.pop("controls")
    with pytest.raises(ParameterError) as ei:
        reconcile(dets, controls, **kwargs)
    assert ei.value.parameter == param


def test_real_detections_constant_record_set_aside():
    t = np.arange(2000) * 1e-3
    ring = 0.1 + 1e-3 * np.exp(-0.5 * t) * np.cos(40.0 * t)
    dets = [detect(ring, dt=1e-3), detect(np.full(2000, 0.1), dt=1e-3)]
    out = reconcile(dets, np.array([0.0, 1.0]), names=["ring.csv", "flat.csv"])
    assert out[0] == dets[0]
    (f,) = _aside(out[1])
    assert "flat.csv" in f.message


def _sweep(mu_star: float = 1.0, n: int = 10, law: float = 0.5) -> tuple[np.ndarray, list[float]]:
    """Controls and the soft mode's sqrt|sigma2| of a sweep: |sigma2| ~ (mu* - mu)^law."""
    mu = np.linspace(0.0, 0.9 * mu_star, n)
    return mu, [50.0 * (mu_star - m) ** (law / 2) for m in mu]


@pytest.mark.parametrize("law", [0.5, 1.0])
def test_clean_sweeps_on_their_branch_are_unchanged(law: float):
    """A saddle-node (|sigma2| ~ sqrt) or pitchfork (~ linear) branch, a higher mode in every
    record: nothing is moved or set aside, however steep the last steps."""
    mu, roots = _sweep(law=law)
    dets = [_det(r, 4.0 * 50.0) for r in roots]
    out = reconcile(dets, mu, names=[f"r{i}" for i in range(mu.size)])
    assert out == tuple(dets)


def test_a_drift_read_as_the_fundamental_is_replaced_by_the_branch_mode():
    mu, roots = _sweep()
    dets = [_det(r, 200.0) for r in roots]
    dets[4] = _det(0.7, roots[4], 200.0)  # a slow spurious mode first
    out = reconcile(dets, mu, names=[f"r{i}.csv" for i in range(mu.size)])
    f = out[4].fundamental
    assert f.index == 1 and math.isclose(math.sqrt(-f.sigma2), roots[4])
    assert "fundamental_reconciled" in out[4].flag_codes and not _aside(out[4])
    assert all(out[k] == dets[k] for k in range(mu.size) if k != 4)


def test_an_outlier_with_no_mode_on_the_branch_is_set_aside_by_name():
    mu, roots = _sweep()
    dets = [_det(r, 200.0) for r in roots]
    dets[6] = _det(3.0 * roots[6])  # only a wrong mode in it
    names = [f"rec_{i:02d}.npz" for i in range(mu.size)]
    out = reconcile(dets, mu, names=names)
    (f,) = _aside(out[6])
    assert "rec_06.npz" in f.message and "branch" in f.message
    assert sum(bool(_aside(d)) for d in out) == 1


def test_the_last_record_may_drop_but_not_jump_to_a_higher_mode():
    mu, roots = _sweep()
    dets = [_det(r, 200.0) for r in roots]
    drop = [*dets[:-1], _det(0.2 * roots[-2], 200.0)]  # a steep slowdown at the end: kept
    assert reconcile(drop, mu, names=[str(i) for i in range(mu.size)]) == tuple(drop)
    jump = [*dets[:-1], _det(200.0)]  # the soft mode missed, a higher mode taken: set aside
    out = reconcile(jump, mu, names=[str(i) for i in range(mu.size)])
    assert _aside(out[-1]) and not any(_aside(d) for d in out[:-1])


def test_one_outlier_does_not_move_the_prediction():
    """The issue's rule: a single outlier record must not move the answer outside the interval
    it has without it. Saddle-node sweep with noise; the outlier is set aside, and the
    prediction from the kept records equals the one without the outlier."""
    from service.analysis.predict import predict

    rng = np.random.default_rng(7)
    mu = np.linspace(0.0, 0.85, 12)
    s2 = -2500.0 * np.sqrt(1.0 - mu) * (1 + 0.002 * rng.standard_normal(mu.size))
    std = 0.002 * np.abs(s2)

    def det(s: float, sd: float) -> Detection:
        m = replace(_mode(math.sqrt(-s)), sigma2=s, sigma2_std=sd)
        return Detection((m,), Fundamental(m, 0), 0.0, 1e-3, (), "varpro", 1e-3, 40.0)

    dets = [det(s, sd) for s, sd in zip(s2, std, strict=True)]
    bad = dets.copy()
    bad[7] = det(-0.25 * 2500.0, 1.0)  # a slow spurious fundamental, nothing else
    out = reconcile(bad, mu, names=[f"r{i}" for i in range(mu.size)])
    keep = [k for k, d in enumerate(out) if not _aside(d)]
    assert keep == [k for k in range(mu.size) if k != 7]
    ref = predict(np.delete(mu, 7), np.delete(s2, 7), sigma2_std=np.delete(std, 7))
    got = predict(mu[keep], np.array([out[k].fundamental.sigma2 for k in keep]),
                  sigma2_std=np.array([out[k].fundamental.sigma2_std for k in keep]))  # fmt: skip
    lo, hi = ref.mu_star_interval
    assert lo <= got.mu_star <= hi and abs(ref.mu_star - 1.0) < 0.05
    # without the branch test the outlier moves the answer (the test can fail)
    raw = predict(mu, np.array([d.fundamental.sigma2 for d in bad]),
                  sigma2_std=np.array([d.fundamental.sigma2_std for d in bad]))  # fmt: skip
    assert not lo <= raw.mu_star <= hi


def _repeats_after_a_wrong_record(wrong: Detection, n_repeats: int) -> tuple[list, np.ndarray]:
    """A pitchfork sweep whose record at 0.6 reads ``wrong``, then ``n_repeats`` records at
    0.7 that all read the branch."""
    mu = np.array([0.0, 0.15, 0.3, 0.45, 0.6, 0.7])
    roots = [50.0 * (1.0 - m) ** 0.5 for m in mu]
    dets = [_det(r, 200.0) for r in roots[:4]] + [wrong]
    dets += [_det(roots[5], 200.0) for _ in range(n_repeats)]
    controls = np.array([*mu[:5], *([mu[5]] * n_repeats)])
    return dets, controls


@pytest.mark.parametrize("n_repeats", [2, 3, 6])
def test_repeats_at_one_control_outvote_the_record_beside_them(n_repeats: int):
    """Repeats at one control that agree define the branch: the single record before them that
    read too slow a mode is set aside, not the repeats one after the other (the lab then
    spends its records repeating that control)."""
    roots6 = 50.0 * 0.4**0.5
    dets, c = _repeats_after_a_wrong_record(_det(0.45 * roots6, 200.0), n_repeats)
    names = [f"rec_{i:02d}.csv" for i in range(c.size)]
    out = reconcile(dets, c, names=names)
    aside = [names[k] for k, d in enumerate(out) if _aside(d)]
    assert aside == ["rec_04.csv"], aside


def test_the_record_beside_repeats_takes_its_branch_mode():
    """... and when that record has a mode on the branch, it becomes its fundamental (no record
    is lost)."""
    roots6 = 50.0 * 0.4**0.5
    dets, c = _repeats_after_a_wrong_record(_det(0.45 * roots6, roots6, 200.0), 3)
    out = reconcile(dets, c, names=[f"r{i}" for i in range(c.size)])
    assert not any(_aside(d) for d in out)
    assert out[4].fundamental.index == 1 and "fundamental_reconciled" in out[4].flag_codes
    assert all(out[k] == dets[k] for k in range(c.size) if k != 4)


def test_a_neighbour_read_with_a_large_error_sets_no_record_aside():
    """A record whose fundamental carries a 150 % error stays within its own tolerance; it
    must not put the precise records beside it off the branch either."""
    mu, roots = _sweep(n=8, law=1.0)
    dets = [_det(r, 200.0) for r in roots]
    m = replace(_mode(0.5 * roots[6]), sigma2_std=1.5 * (0.5 * roots[6]) ** 2)
    dets[6] = replace(dets[6], modes=(m, *dets[6].modes[1:]), fundamental=Fundamental(m, 0))
    out = reconcile(dets, mu, names=[f"r{i}" for i in range(mu.size)])
    assert not any(_aside(d) for d in out)


def test_an_ambiguous_record_is_treated_before_its_neighbour():
    """The last two records contradict each other and either alone would be on the branch (the
    one before reads too slow a mode, or the last goes against the trend): the one whose
    detector doubts its fundamental (flag fundamental_ambiguous) is set aside, whichever it
    is."""
    mu, roots = _sweep(n=8, law=1.0)
    base = [_det(r, 200.0) for r in roots]
    base[6] = _det(0.45 * roots[6], 200.0)
    flag = Flag("fundamental_ambiguous", "test")
    for doubted in (6, 7):
        dets = list(base)
        dets[doubted] = replace(dets[doubted], flags=(*dets[doubted].flags, flag))
        out = reconcile(dets, mu, names=[f"r{i}" for i in range(mu.size)])
        assert [k for k, d in enumerate(out) if _aside(d)] == [doubted], doubted
