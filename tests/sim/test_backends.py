"""The backend registry: one vocabulary, one resolution per scene, clean failures, auto."""

from __future__ import annotations

import json
import typing

import pytest

from sim import ACTUATIONS, MODELS, simulate
from sim.backends import BACKENDS, FINITE_SHORTENING
from sim.cosserat.rod import cowper_rectangle, shear_ratio
from sim.errors import ParameterError, SimulationError
from sim.scene import Scene, SceneError
from sim.select import choose_model


def test_schema_literals_are_sims_vocabulary() -> None:
    from service.schemas import simulations

    assert typing.get_args(simulations.Model) == MODELS
    assert typing.get_args(simulations.Actuation) == ACTUATIONS
    assert set(BACKENDS) | {"auto"} == set(MODELS)


def test_errors_carry_their_parameter() -> None:
    with pytest.raises(SceneError) as e:
        Scene(mu=float("nan"))
    assert isinstance(e.value, ParameterError) and e.value.parameter == "mu"
    with pytest.raises(SceneError) as e:
        Scene(elements=7)
    assert (e.value.parameter, e.value.value) == ("elements", 7)


def test_rectangle_shear_coefficient() -> None:
    assert cowper_rectangle(0.0) == pytest.approx(5 / 6)
    assert cowper_rectangle(0.5) == pytest.approx(6 / 7)
    assert shear_ratio(0.0) == pytest.approx(5 / 12)  # kappa G / E = (5/6) / 2


ROD = Scene(actuation="asymmetric", slenderness=1e-2, elements=50)


def test_every_command_of_a_scene_uses_one_resolution() -> None:
    scene = Scene(actuation="antisymmetric", mu=1.0, slenderness=1e-2, rtol=2e-3,
                  duration=0.3)  # fmt: skip
    sig = simulate(scene, "cosserat")
    bif = BACKENDS["cosserat"].bifurcation(scene)
    sp = BACKENDS["cosserat"].spectrum(scene, 2)
    n = sig.info["elements"]
    assert bif.resolution.size == n == sp.resolution.size
    assert sig.info["resolution"].size == n and sig.info["resolution"].rtol == 2e-3
    err = bif.resolution.mu_star_error
    assert 0 < err <= 0.5 * 2e-3 * bif.mu_star  # the policy's target
    assert sig.info["sigma2"][0] == pytest.approx(sp.sigma2[0], rel=1e-9)
    assert 0 < sig.info["sigma2_error"] < 1e-2 and sig.info["error"].total > 0


@pytest.mark.slow
def test_richardson_estimate_is_the_actual_error() -> None:
    """The estimated mu* error at n = 50 against the n = 50 -> n = 100 -> extrapolated change."""
    b50 = BACKENDS["cosserat"].bifurcation(ROD)
    b100 = BACKENDS["cosserat"].bifurcation(ROD.with_(elements=100))
    actual = (b100.mu_star - b50.mu_star) * 4 / 3  # order 2
    assert b50.mu_star_error == pytest.approx(abs(actual), rel=0.05)


@pytest.mark.parametrize(
    ("scene", "command"),
    [
        (ROD.with_(mu=1.7344), "simulate"),  # past the n = 50 fold at 1.7307 (not another state)
        (ROD.with_(mu=1.7344), "spectrum"),
        pytest.param(Scene(actuation="asymmetric", mu=1.78, elements=50), "simulate",
                     marks=pytest.mark.slow),
        pytest.param(Scene(actuation="symmetric", mu=2.005, elements=24), "simulate",
                     marks=pytest.mark.slow),  # past the secondary fold
        pytest.param(Scene(actuation="symmetric", mu=1.97, elements=24), "simulate",
                     marks=pytest.mark.slow),  # U_A unstable past the pitchfork (1.9663)
        pytest.param(Scene(actuation="antisymmetric", mu=2.1, elements=24), "simulate",
                     marks=pytest.mark.slow),  # merged into S_B
    ],
)
def test_rod_past_its_transition_is_one_clean_error(scene: Scene, command: str) -> None:
    with pytest.raises(SimulationError) as e:
        if command == "simulate":
            simulate(scene.with_(duration=0.2), "cosserat")
        else:
            BACKENDS["cosserat"].spectrum(scene, 2)
    assert e.value.parameter == "mu" and e.value.value == scene.mu
    msg = str(e.value)
    assert "\n" not in msg and f"mu={scene.mu!r}" in msg and "mu*" in msg


@pytest.mark.parametrize("model", ["euler-beam", "normal-form"])
@pytest.mark.parametrize(("actuation", "mu"), [("asymmetric", 1.79), ("symmetric", 2.05)])
def test_beam_and_normal_form_past_the_transition(model: str, actuation: str, mu: float) -> None:
    with pytest.raises(SimulationError) as e:
        simulate(Scene(actuation=actuation, mu=mu), model)
    assert e.value.parameter == "mu" and "mu*" in str(e.value)


def test_cli_past_the_fold_exits_2_with_one_line(tmp_path, capsys) -> None:
    from service.cli import main

    argv = ["spectrum", "--model", "cosserat", "--actuation", "asymmetric", "--mu", "1.7344",
            "--slenderness", "0.01", "--elements", "50", "--json"]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "mu=1.7344" in err and "mu*" in err
    problem = json.loads(out)
    assert problem["status"] == 422 and problem["field"] == "mu" and problem["value"] == 1.7344


AUTO_TABLE = [
    # scene, rtol, expected backend (and beam method)
    (Scene(actuation="symmetric", mu=2 - 1e-5, kick=1e-6, end_shortening=1e-5,
           slenderness=1e-6), 1e-2, ("normal-form", None)),
    (Scene(mu=0.5, kick=1e-3, end_shortening=1e-4, slenderness=1e-5), 1e-2,
     ("euler-beam", "modal")),
    (Scene(mu=1.7, kick=0.5, end_shortening=1e-4, slenderness=1e-5), 1e-2,
     ("euler-beam", "nonlinear")),
    (Scene(mu=1.0, end_shortening=2e-2, slenderness=1e-2), 1e-2, ("cosserat", None)),
]


@pytest.mark.parametrize(("scene", "rtol", "expected"), AUTO_TABLE)
def test_auto_picks_the_cheapest_accurate_backend(scene, rtol, expected) -> None:
    c = choose_model(scene.with_(rtol=rtol))
    assert (c.model, c.method) == expected and c.met
    assert 0 < c.estimate.total <= rtol
    assert c.estimate.model > 0 and c.estimate.discretisation > 0  # never an error of 0
    assert c.model in c.reason and f"{rtol:g}" in c.reason


def test_auto_simulation_names_its_backend_and_estimate() -> None:
    sig = simulate(AUTO_TABLE[1][0].with_(rtol=1e-2), "auto")
    auto = sig.info["auto"]
    assert sig.model == auto.model == "euler-beam" and auto.estimate.total > 0
    assert "euler-beam" in auto.reason


@pytest.mark.slow
@pytest.mark.parametrize("actuation", ACTUATIONS)
def test_beam_finite_shortening_error_is_the_elastica_s(actuation: str) -> None:
    """The beam's model-error coefficient against the exact inextensible elastica."""
    from sim.cosserat import elastica
    from sim.euler_beam import bifurcation

    d = 1e-2
    measured = (elastica.mu_star(actuation, d) / bifurcation(actuation).mu_star - 1) / d
    assert measured == pytest.approx(FINITE_SHORTENING[actuation], rel=0.05)


@pytest.mark.slow
@pytest.mark.parametrize(("actuation", "elastica_mu"),
                         [("asymmetric", 1.7823135859899482), ("symmetric", 2.00189981836877),
                          ("antisymmetric", 2.0020885835399502)])  # fmt: skip
def test_thin_rod_meets_the_elastica_at_the_default_accuracy(actuation, elastica_mu) -> None:
    """dL/L = 1e-2, h/L = 1e-3, default rtol: within 1e-3 of the exact elastica (recomputed by
    tests/cosserat/test_statics.py::test_elastica_reference_values)."""
    b = BACKENDS["cosserat"].bifurcation(Scene(actuation=actuation))
    assert abs(b.mu_star - elastica_mu) < 1e-3
