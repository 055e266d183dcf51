"""Snap-through for users: the paper's protocol, its scaling laws, and the normal form."""

from __future__ import annotations

import numpy as np
import pytest

from sim.errors import ParameterError
from sim.scene import Scene
from sim.snap import snap

EXPONENT = {"asymmetric": -0.25, "symmetric": -0.5, "antisymmetric": -0.5}
PROTOCOL = {"asymmetric": ("U_A", "U_B", 1.0), "symmetric": ("U_A", "U_B", 1.0),
            "antisymmetric": ("S_B", "U_A", -1.0)}  # fmt: skip


def _exponent(actuation: str, model: str, dmus) -> tuple[float, list]:
    runs = [snap(Scene(actuation=actuation, damping=0.0), model, d) for d in dmus]
    times = [r.snap_time for r in runs]
    assert None not in times
    return float(np.polyfit(np.log(dmus), np.log(times), 1)[0]), runs


@pytest.mark.parametrize("actuation", list(EXPONENT))
def test_normal_form_snap_time_scaling_over_two_decades(actuation: str) -> None:
    dmus = [1e-7, 1e-6, 1e-5] if actuation == "asymmetric" else [1e-5, 1e-4, 1e-3]
    slope, runs = _exponent(actuation, "normal-form", dmus)
    assert slope == pytest.approx(EXPONENT[actuation], abs=0.02)
    frm, to, side = PROTOCOL[actuation]
    r = runs[0]
    assert (r.from_branch, r.to_branch) == (frm, to)
    assert np.sign(r.mu - r.mu_star) == side


def test_bad_dmu_is_named() -> None:
    with pytest.raises(ParameterError) as e:
        snap(Scene(), "euler-beam", -1e-3)
    assert e.value.parameter == "dmu"


def _rescaled_time(r) -> float:
    """First time |A| reaches half the normal form's amplitude scale at the probe,
    phi0(probe) sqrt(a1 dmu / a2) or phi0(probe) sqrt(|b1| dmu / b2) (the distance of its
    equilibria), so that the normal form's times scale exactly as dmu^(-1/4) (saddle-node) and
    dmu^(-1/2) (pitchforks, whose initial velocity is proportional to dmu)."""
    from sim.normal_form import normal_form

    nf = normal_form(r.actuation)
    c = nf.coefficients
    k = np.sqrt(c["a1"] / c["a2"]) if nf.saddle_node else np.sqrt(abs(c["b1"] / c["b2"]))
    level = 0.5 * k * abs(float(nf.phi(np.array([r.probe]))[0])) * np.sqrt(r.dmu)
    k = int(np.flatnonzero(np.abs(np.nan_to_num(r.amplitude, nan=np.inf)) >= level)[0])
    a0, a1 = abs(r.amplitude[k - 1]), abs(r.amplitude[k])
    return float(r.t[k - 1] + (level - a0) / (a1 - a0) * (r.t[k] - r.t[k - 1]))


@pytest.mark.slow
@pytest.mark.parametrize("actuation", list(EXPONENT))
def test_beam_snap_time_scaling_and_collapse_on_the_normal_form(actuation: str) -> None:
    """The nonlinear beam over two decades of dmu: the time to reach the normal form's
    amplitude scale (~ sqrt(dmu)) scales as dmu^(-1/4) (saddle-node) and dmu^(-1/2)
    (pitchforks), and the rescaled times collapse on the normal form's. The symmetric decades
    stop at 2e-3, below the secondary fold U_A / W_B (mu* + 0.0119) that ends that pitchfork's
    regime."""
    dmus = [2e-5, 2e-4, 2e-3] if actuation == "symmetric" else [1e-4, 1e-3, 1e-2]
    sc = Scene(actuation=actuation, damping=0.0)
    beam = [_rescaled_time(snap(sc, "euler-beam", d)) for d in dmus]
    nf = [_rescaled_time(snap(sc, "normal-form", d)) for d in dmus]
    slope_nf = np.polyfit(np.log(dmus), np.log(nf), 1)[0]
    slope_beam = np.polyfit(np.log(dmus), np.log(beam), 1)[0]
    assert slope_nf == pytest.approx(EXPONENT[actuation], abs=0.01)
    assert slope_beam == pytest.approx(EXPONENT[actuation], abs=0.05)  # -0.253, -0.496, -0.466
    ratios = [b / n for b, n in zip(beam, nf)]
    if actuation == "asymmetric":
        assert abs(ratios[0] - 1) < 0.05  # measured 0.998
    else:
        # the control step excites the stable modes at O(dmu), which act on the critical one at
        # the order of b1 dmu A itself (the paper's pre-snap oscillations): the collapse holds
        # to that order at every dmu (measured 0.90-1.24), not better as dmu -> 0
        assert all(abs(r - 1) < 0.3 for r in ratios)


def test_one_bifurcation_type_for_every_backend() -> None:
    from sim.backends import BACKENDS
    from sim.results import Bifurcation

    scene = Scene(actuation="asymmetric", slenderness=1e-2, elements=24)
    bifs = [BACKENDS[m].bifurcation(scene) for m in ("euler-beam", "normal-form", "cosserat")]
    assert all(type(b) is Bifurcation and b.transition == "saddle-node" for b in bifs)
    assert [b.model for b in bifs] == ["euler-beam", "normal-form", "cosserat"]
    assert all(b.mu_star_error > 0 for b in bifs)


def test_cli_snap_json_and_csv(capsys, tmp_path) -> None:
    import csv
    import json

    from service.cli import main

    out = tmp_path / "snap.csv"
    assert main(["snap", "--model", "normal-form", "--actuation", "asymmetric", "--dmu",
                 "1e-4", "--out", str(out), "--json"]) == 0  # fmt: skip
    doc = json.loads(capsys.readouterr().out)
    assert {"actuation", "model", "dmu", "snap_time", "from_branch", "to_branch",
            "samples"} <= set(doc)  # fmt: skip
    assert (doc["from_branch"], doc["to_branch"]) == ("U_A", "U_B") and doc["snap_time"] > 0
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["t", "amplitude"] and len(rows) == doc["samples"] + 1


@pytest.mark.slow
@pytest.mark.parametrize("actuation", list(EXPONENT))
def test_rod_snap_follows_the_normal_form_near_its_own_mu_star(actuation: str) -> None:
    """The rod (h/L = 1e-2, 48 elements) from its own mu*: the snap time at dmu = 1e-3 within
    10 % of the normal form's (which knows only the beam's coefficients)."""
    scene = Scene(actuation=actuation, slenderness=1e-2, elements=48, damping=0.0)
    rod = snap(scene, "cosserat", 1e-3)
    nf = snap(scene, "normal-form", 1e-3)
    assert rod.snap_time == pytest.approx(nf.snap_time, rel=0.1)
