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


@pytest.mark.slow
@pytest.mark.parametrize("actuation", list(EXPONENT))
def test_beam_snap_time_scaling_and_collapse_on_the_normal_form(actuation: str) -> None:
    """The nonlinear beam over two decades of dmu: the saddle-node's -1/4, the pitchforks'
    -1/2; rescaled times T dmu^(-exponent) collapse on the normal form's as dmu -> 0."""
    dmus = [1e-4, 1e-3, 1e-2]
    slope, runs = _exponent(actuation, "euler-beam", dmus)
    assert slope == pytest.approx(EXPONENT[actuation], abs=0.06)
    nf = [snap(Scene(actuation=actuation, damping=0.0), "normal-form", d).snap_time
          for d in dmus]  # fmt: skip
    ratios = [r.snap_time / t for r, t in zip(runs, nf)]
    assert abs(ratios[0] - 1) < 0.15  # collapse at the smallest dmu
    assert abs(ratios[0] - 1) <= abs(ratios[-1] - 1) + 0.02  # and it improves towards mu*


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
