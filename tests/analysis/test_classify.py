"""Classifier: synthetic sweeps from exact laws with injected truth, and the Euler beam.

Synthetic laws along the measured stable branch, ``x = mu* - mu`` (service.analysis.classify):

* saddle-node: ``|sigma^2| = C x^(1/2) (1 + c1 x^(1/2) + c2 x)``,
  ``w = w* - g x^(1/2) (1 + d x^(1/2))``
* subcritical pitchfork: ``|sigma^2| = C x (1 + c1 x + c2 x^2)``, ``w = w* + g x + e x^2``
* supercritical pitchfork: ``|sigma^2| = C x (1 + c1 x + c2 x^2)``,
  ``w = w* + g x^(1/2) (1 + d x) + e x``

The Euler-beam tests use ``sim.euler_beam`` (written independently) as the reference: its
``bifurcation(actuation)`` gives mu* and the transition, ``spectrum`` the exact sigma^2.
"""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest

from service import convert
from service.analysis.classify import Classification, classify
from service.analysis.common import Flag

KINDS = ("saddle-node", "subcritical-pitchfork", "supercritical-pitchfork")
A_OF = {"saddle-node": 0.25, "subcritical-pitchfork": 0.5, "supercritical-pitchfork": 0.5}
B_OF = {"saddle-node": 0.5, "subcritical-pitchfork": 1.0, "supercritical-pitchfork": 0.5}


def law(kind: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``|sigma^2|`` and ``w`` at distances ``x`` (> 0) below mu*."""
    if kind == "saddle-node":
        s = 30.0 * x**0.5 * (1 + 0.8 * x**0.5 - 0.3 * x)
        w = 0.3 - 0.2 * x**0.5 * (1 + 0.4 * x**0.5) + 0.05 * x
    elif kind == "subcritical-pitchfork":
        s = 40.0 * x * (1 - 0.3 * x + 0.1 * x**2)
        w = 0.25 + 0.3 * x - 0.1 * x**2
    elif kind == "supercritical-pitchfork":
        s = 40.0 * x * (1 + 0.5 * x - 0.2 * x**2)
        w = 0.1 + 0.3 * x**0.5 * (1 - 0.2 * x) + 0.1 * x
    else:  # pragma: no cover
        raise ValueError(kind)
    return s, w


def sweep(
    kind: str,
    *,
    mu_star: float = 1.78,
    n: int = 20,
    rel: float = 1e-3,
    w_noise: float = 1e-6,
    seed: int = 0,
    xmin: float = 1e-4,
    xmax: float | None = None,
) -> dict[str, np.ndarray]:
    """A geometric approach to mu* (distances from ``xmax`` down to ``xmin``) with relative
    Gaussian noise ``rel`` on ``sigma2`` and absolute noise ``w_noise`` on ``w``."""
    rng = np.random.default_rng(seed)
    x = np.geomspace(mu_star if xmax is None else xmax, xmin, n)
    s, w = law(kind, x)
    sd = rel * s
    return {
        "mu": mu_star - x,
        "sigma2": -(s + sd * rng.standard_normal(n)),
        "sigma2_std": sd,
        "w_static": w + w_noise * rng.standard_normal(n),
        "x": x,
    }


def overdamped_rates(
    kind: str, xi: float, *, mu_star: float = 1.78, n: int = 20, rel: float = 1e-3, seed: int = 0
) -> dict[str, np.ndarray]:
    """What an FFT / decay-rate measurement gives with damping ``xi``: the pole modulus
    ``sqrt|sigma^2|`` when under-damped, the slow rate ``xi/2 - sqrt(xi^2/4 - |sigma^2|)`` when
    over-damped (paper, Appendix "Over-damped boundary layer")."""
    rng = np.random.default_rng(seed)
    x = np.geomspace(mu_star, 1e-5, n)
    s, w = law(kind, x)
    w0 = np.sqrt(s)
    r = np.where(w0 >= xi / 2, w0, xi / 2 - np.sqrt(np.maximum(xi**2 / 4 - s, 0.0)))
    rsd = rel * r
    return {
        "mu": mu_star - x,
        "omega": r + rsd * rng.standard_normal(n),
        "omega_std": rsd,
        "w_static": w + 1e-6 * rng.standard_normal(n),
        "overdamped": w0 < xi / 2,
    }


# --------------------------------------------------------------------------------------------
# synthetic sweeps
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", KINDS)
def test_classifies_each_transition_with_static_data(kind: str) -> None:
    d = sweep(kind, seed=1)
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w_static"],
                 w_static_std=1e-6)
    assert isinstance(c, Classification)
    assert c.transition == kind
    assert c.probabilities[kind] > 0.99
    assert set(c.probabilities) == set(KINDS)
    assert math.isclose(sum(c.probabilities.values()), 1.0, rel_tol=1e-12)
    assert c.regime == "underdamped"
    # exponents: free estimates near the injected ones
    assert abs(c.a - A_OF[kind]) < 0.02
    assert abs(c.b - B_OF[kind]) < 0.05
    # mu*: injected 1.78, within 5 sigma and far better than the paper's 1e-4 level
    assert abs(c.mu_star - 1.78) < 5 * c.mu_star_std
    assert abs(c.mu_star - 1.78) < 2e-6
    assert not any(f.code == "poor_fit" for f in c.flags)


@pytest.mark.parametrize("kind", KINDS)
def test_without_static_data_pitchforks_are_not_split(kind: str) -> None:
    d = sweep(kind, seed=2)
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    want = "saddle-node" if kind == "saddle-node" else "pitchfork"
    assert c.transition == want
    assert set(c.probabilities) == {"saddle-node", "pitchfork"}
    assert math.isnan(c.b) and any(f.code == "no_static_data" for f in c.flags)


def test_half_integer_corrections_matter_near_a_fold() -> None:
    """Near a fold sigma^2 is a series in x^(1/2): a pitchfork-like law with integer
    corrections cannot stand in for it (its probability is ~0 on a wide window)."""
    d = sweep("saddle-node", rel=1e-4, seed=3)
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    assert c.transition == "saddle-node"
    assert c.probabilities["pitchfork"] < 1e-6


def test_supercritical_named_a_pitchfork_without_the_static_noise() -> None:
    """Static records without their noise (a plain table): a supercritical pitchfork's are
    told from a saddle-node's, not from an imperfect softening structure's (which snaps): named
    ``pitchfork`` with the flag ``static_noise_unknown``; the same records with their noise are
    named supercritical (the other types are unaffected)."""
    d = sweep("supercritical-pitchfork", seed=4)
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w_static"])
    assert c.transition == "pitchfork"
    assert any(f.code == "static_noise_unknown" for f in c.flags)
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w_static"],
                 w_static_std=1e-6)
    assert c.transition == "supercritical-pitchfork"
    assert not any(f.code == "static_noise_unknown" for f in c.flags)
    for kind in ("saddle-node", "subcritical-pitchfork"):
        d = sweep(kind, seed=4)
        c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w_static"])
        assert c.transition == kind


def test_noise_estimated_when_not_given() -> None:
    d = sweep("supercritical-pitchfork", rel=1e-3, seed=4)
    c = classify(d["mu"], d["sigma2"], w_static=d["w_static"], w_static_std=1e-6)
    assert c.transition == "supercritical-pitchfork"
    flag = next(f for f in c.flags if f.code == "noise_estimated")
    assert isinstance(flag, Flag) and "relative noise" in flag.message
    assert abs(c.mu_star - 1.78) < 5 * c.mu_star_std


def test_exponent_far_from_candidates_is_undetermined() -> None:
    """|sigma^2| ~ x^2 (a = 1: what over-damped FFT data given as sigma2 look like)."""
    x = np.geomspace(1.0, 1e-4, 15)
    s = x**2 * (1 + 0.2 * x)
    rng = np.random.default_rng(0)
    c = classify(1 - x, -(s * (1 + 1e-3 * rng.standard_normal(x.size))), sigma2_std=1e-3 * s)
    assert c.transition == "undetermined"
    assert abs(c.a - 1.0) < 0.05
    assert any(f.code == "exponent_off" for f in c.flags)


def test_flat_data_are_undetermined_and_flagged() -> None:
    x = np.geomspace(1.0, 1e-4, 15)
    rng = np.random.default_rng(0)
    s = 5 * (1 + 1e-3 * rng.standard_normal(x.size))
    c = classify(1 - x, -s, sigma2_std=5e-3 * np.ones(x.size))
    assert c.transition == "undetermined"
    assert {"ambiguous", "interval_unbounded"} <= {f.code for f in c.flags}


def test_three_points_work_and_flag_assumed_noise() -> None:
    mu = np.array([0.9, 0.99, 0.999])
    c = classify(mu, -(1 - mu))
    assert math.isfinite(c.mu_star) and abs(c.mu_star - 1) < 1e-3
    codes = {f.code for f in c.flags}
    assert {"noise_assumed", "few_points_near"} <= codes


def test_wire_document_is_strict_json() -> None:
    d = sweep("saddle-node", seed=5)
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"])
    doc = json.loads(json.dumps(convert.classification(c).model_dump(mode="json"),
                                allow_nan=False))  # fmt: skip
    assert doc["transition"] == "saddle-node"
    assert doc["b"] is None  # NaN (no static data) becomes null, with its flag
    assert any(f["code"] == "no_static_data" for f in doc["flags"])
    for key in ("a", "a_std", "mu_star", "mu_star_std", "probabilities", "regime", "flags"):
        assert key in doc


def test_unit_agnostic_control_and_time() -> None:
    """mu in degrees (affine change) and sigma2 in another time unit: same answer, mapped."""
    d = sweep("subcritical-pitchfork", seed=6)
    c0 = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w_static"])
    k, off, tu = 180 / math.pi, 3.0, 1e3**2
    c1 = classify(
        off + k * d["mu"],
        tu * d["sigma2"],
        sigma2_std=tu * d["sigma2_std"],
        w_static=1e3 * d["w_static"],
    )
    assert c1.transition == c0.transition
    assert c1.mu_star == pytest.approx(off + k * c0.mu_star, rel=1e-9, abs=1e-7 * k)
    assert c1.mu_star_std == pytest.approx(k * c0.mu_star_std, rel=1e-2)
    assert c1.a == pytest.approx(c0.a, abs=1e-4)


# --------------------------------------------------------------------------------------------
# over-damped boundary layer (omega data: FFT period / slow decay rate)
# --------------------------------------------------------------------------------------------


def test_overdamped_layer_omega_data_saddle_node() -> None:
    """A fold seen through its slow rate: the nearest points follow the doubled exponent
    (a = 1/2, like a pitchfork); the fitted damping recovers the crossover and the type."""
    d = overdamped_rates("saddle-node", xi=2.0, seed=0)
    assert d["overdamped"].sum() >= 4  # the layer is really sampled
    c = classify(d["mu"], omega=d["omega"], omega_std=d["omega_std"], w_static=d["w_static"])
    assert c.transition == "saddle-node"
    assert c.regime == "overdamped"
    assert abs(c.a - 0.5) < 0.1  # doubled
    assert 1.0 < c.damping < 4.0
    assert any(f.code == "overdamped" for f in c.flags)
    assert abs(c.mu_star - 1.78) < 1e-6


@pytest.mark.slow
@pytest.mark.parametrize(
    ("kind", "xi"), [("subcritical-pitchfork", 0.5), ("supercritical-pitchfork", 0.5)]
)
def test_overdamped_layer_omega_data_pitchforks(kind: str, xi: float) -> None:
    d = overdamped_rates(kind, xi=xi, seed=0)
    assert d["overdamped"].sum() >= 4
    c = classify(d["mu"], omega=d["omega"], omega_std=d["omega_std"], w_static=d["w_static"],
                 w_static_std=1e-6)
    assert c.transition == kind
    assert c.regime == "overdamped"
    assert abs(c.a - 1.0) < 0.1
    assert abs(c.mu_star - 1.78) < 1e-6


def test_pole_sigma2_with_known_damping_sets_regime() -> None:
    """sigma2 = -s1 s2 keeps the undamped law in the layer: type and a unchanged, regime told
    by the damping."""
    d = sweep("subcritical-pitchfork", xmin=1e-5, seed=7)
    xi = 2 * math.sqrt(-d["sigma2"][-3])  # the 3 nearest points are over-damped
    c = classify(d["mu"], d["sigma2"], sigma2_std=d["sigma2_std"], w_static=d["w_static"],
                 damping=xi)  # fmt: skip
    assert c.transition == "subcritical-pitchfork"
    assert c.regime == "overdamped"
    assert abs(c.a - 0.5) < 0.02


# --------------------------------------------------------------------------------------------
# validation at the door
# --------------------------------------------------------------------------------------------

_MU = [0.0, 0.5, 0.9, 0.99]
_S2 = [-4.0, -2.0, -0.4, -0.04]


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"mu": [0.0, 0.5], "sigma2": [-1.0, -0.5]}, ["mu", "at least 3", "2"]),
        ({"mu": [0.0, 0.5, math.nan, 1.0], "sigma2": _S2}, ["mu", "finite", "nan"]),
        ({"mu": _MU, "sigma2": [-4.0, -2.0, -0.4]}, ["sigma2", "length", "3"]),
        ({"mu": [0.0, 0.5, 0.5, 0.5], "sigma2": _S2}, ["mu", "3 distinct", "got 2 in 4 rows"]),
        ({"mu": [0.0, 0.9, 0.5, 0.99], "sigma2": _S2}, ["mu", "increasing", "0.9"]),
        ({"mu": _MU, "sigma2": [-4.0, -2.0, 0.3, -0.04]}, ["sigma2", "< 0", "0.3"]),
        ({"mu": _MU, "sigma2": [-4.0, -2.0, math.inf, -0.04]}, ["sigma2", "finite", "inf"]),
        ({"mu": _MU, "sigma2": _S2, "sigma2_std": [1, 1, 0, 1]}, ["sigma2_std", "> 0", "0"]),
        ({"mu": _MU}, ["sigma2", "omega", "neither"]),
        ({"mu": _MU, "sigma2": _S2, "omega": [1, 1, 1, 1]}, ["sigma2", "omega", "both"]),
        ({"mu": _MU, "omega": [2.0, 1.0, -0.5, 0.2]}, ["omega", "> 0", "-0.5"]),
        ({"mu": _MU, "sigma2": _S2, "w_static": [0.1, 0.2]}, ["w_static", "length", "2"]),
        ({"mu": _MU, "sigma2": _S2, "damping": -1.0}, ["damping", "-1.0"]),
        ({"mu": _MU, "sigma2": _S2, "min_probability": 0.0}, ["min_probability", "0.0"]),
        ({"mu": [[0.0, 1.0]], "sigma2": _S2}, ["mu", "one-dimensional"]),
        ({"mu": ["a", "b", "c"], "sigma2": _S2[:3]}, ["mu", "numbers"]),
    ],
)
def test_validation_names_parameter_and_value(kwargs: dict, words: list[str]) -> None:
    kw = dict(kwargs)
    mu = kw.pop("mu")
    with pytest.raises(ValueError) as ei:
        classify(mu, **kw)
    msg = str(ei.value)
    for w in words:
        assert w in msg, (w, msg)


# --------------------------------------------------------------------------------------------
# Euler beam (independent reference: sim.euler_beam)
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def beam_sweeps() -> dict[str, dict]:
    """Exact beam spectra and static deflections at 20 points approaching mu*."""
    pytest.importorskip("sim.euler_beam")
    return _beam_sweeps()


@functools.cache
def _beam_sweeps() -> dict[str, dict]:
    import sim.euler_beam as beam

    out = {}
    for act in ("asymmetric", "symmetric", "antisymmetric"):
        b = beam.bifurcation(act)
        x = np.geomspace(0.999 * b.mu_star, 1e-5, 20)
        mu = b.mu_star - x
        s2 = np.array([beam.spectrum(act, m, "U_A", modes=3).sigma2[0] for m in mu])
        w = np.array([beam.equilibrium(act, m, "U_A").w_quarter for m in mu])
        out[act] = {"mu": mu, "sigma2": s2, "w": w, "mu_star": b.mu_star, "kind": b.transition}
    return out


BEAM_KIND = {
    "asymmetric": "saddle-node",
    "symmetric": "subcritical-pitchfork",
    "antisymmetric": "supercritical-pitchfork",
}


@pytest.mark.parametrize("act", list(BEAM_KIND))
@pytest.mark.parametrize("rel", [pytest.param(1e-6, marks=pytest.mark.slow), 1e-3])
def test_beam_spectra_classified_and_mu_star(beam_sweeps: dict, act: str, rel: float) -> None:
    d = beam_sweeps[act]
    assert d["kind"] == BEAM_KIND[act]  # the reference agrees with the paper
    rng = np.random.default_rng(11)
    sd = rel * np.abs(d["sigma2"])
    s2 = d["sigma2"] + sd * rng.standard_normal(sd.size)
    w = d["w"] + 1e-6 * rng.standard_normal(sd.size)
    c = classify(d["mu"], s2, sigma2_std=sd, w_static=w, w_static_std=1e-6)
    assert c.transition == BEAM_KIND[act]
    assert c.probabilities[BEAM_KIND[act]] > 0.99
    assert abs(c.a - {"saddle-node": 0.25}.get(c.transition, 0.5)) < 0.01
    assert abs(c.b - {"subcritical-pitchfork": 1.0}.get(c.transition, 0.5)) < 0.05
    err = c.mu_star - d["mu_star"]
    assert abs(err) < 1e-7
    assert abs(err) < 5 * c.mu_star_std


@pytest.mark.slow
@pytest.mark.parametrize("act", list(BEAM_KIND))
def test_beam_classification_over_seeds(beam_sweeps: dict, act: str) -> None:
    """Right type in every one of 30 noisy copies (1e-3 relative, 1e-5 on w)."""
    d = beam_sweeps[act]
    for seed in range(30):
        rng = np.random.default_rng(seed)
        sd = 1e-3 * np.abs(d["sigma2"])
        s2 = d["sigma2"] + sd * rng.standard_normal(sd.size)
        w = d["w"] + 1e-5 * rng.standard_normal(sd.size)
        c = classify(d["mu"], s2, sigma2_std=sd, w_static=w, w_static_std=1e-5)
        assert c.transition == BEAM_KIND[act], (seed, c.probabilities)
