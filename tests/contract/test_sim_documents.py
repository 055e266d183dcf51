"""The simulator's and the atlas's documents: built by service.convert from the dataclasses, the
CLI's --json prints exactly that model_dump, and a non-finite number is null (strict JSON)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from service import convert
from service.cli import main
from service.schemas import sim as sim_wire
from sim.results import (
    Bifurcation,
    BifurcationPoint,
    ErrorEstimate,
    Resolution,
    SpectrumSummary,
)


def _cli(capsys: pytest.CaptureFixture[str], *argv: str) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _strict(doc: object) -> object:
    return json.loads(json.dumps(doc, allow_nan=False))


def test_cli_bifurcation_prints_the_converted_model(capsys: pytest.CaptureFixture[str]) -> None:
    from sim.backends import BACKENDS
    from sim.scene import Scene

    doc = _cli(capsys, "bifurcation", "--actuation", "symmetric", "--model", "normal-form")
    b = BACKENDS["normal-form"].bifurcation(Scene(actuation="symmetric"))
    assert doc == convert.bifurcation(b).model_dump(mode="json")
    assert sim_wire.Bifurcation.model_validate(doc).secondary[0].transition == "saddle-node"
    # one set of keys: the strip's fields are null for a backend without a strip
    assert doc["elements"] is None and doc["end_shortening"] is None


def test_cli_spectrum_and_equilibria_are_typed(capsys: pytest.CaptureFixture[str]) -> None:
    sp = _cli(capsys, "spectrum", "--actuation", "asymmetric", "--mu", "1.0", "--modes", "2")
    s = sim_wire.Spectrum.model_validate(sp)
    assert s.omega == pytest.approx([math.sqrt(abs(x)) for x in s.sigma2], rel=1e-12)
    assert "lambda" in sp and "lambda_" not in sp  # the wire name, not the Python one
    eq = _cli(capsys, "equilibria", "--actuation", "asymmetric", "--mu", "1.0")
    e = sim_wire.Equilibria.model_validate(eq)
    assert {x.branch for x in e.equilibria} == {"U_A", "U_B", "S_A", "S_B", "W_A", "W_B"}
    assert e.resolution is not None and e.resolution.model == "euler-beam"


def test_cli_normal_form_and_simulate_auto(capsys, tmp_path) -> None:  # noqa: ANN001
    nf = _cli(capsys, "normal-form", "--actuation", "asymmetric")
    assert set(sim_wire.NormalForm.model_validate(nf).coefficients) == {"a1", "a2"}
    out = tmp_path / "s.csv"
    doc = _cli(capsys, "simulate", "--actuation", "asymmetric", "--mu", "0.5", "--model", "auto",
               "--rtol", "0.05", "--duration", "2", "--out", str(out))  # fmt: skip
    sim = sim_wire.Simulation.model_validate(doc)
    assert sim.auto is not None and sim.auto.model == sim.model
    err = sim.auto.error
    assert err.total == pytest.approx(err.model + err.discretisation)
    assert sim.error is not None and sim.resolution is not None


def test_non_finite_numbers_become_null() -> None:
    res = Resolution("cosserat", 20, None, math.inf, "test")
    second = BifurcationPoint(math.nan, math.inf, "saddle-node", ("U_A",))
    b = Bifurcation("asymmetric", 1.78, math.nan, "saddle-node", ("U_A", "U_B"),
                    secondary=(second,), model="cosserat", resolution=res,
                    end_shortening=1e-2, slenderness=1e-3)  # fmt: skip
    doc = _strict(convert.bifurcation(b).model_dump(mode="json"))
    assert doc["lambda_star"] is None and doc["mu_star_error"] is None
    assert doc["secondary"][0]["mu_star"] is None and doc["resolution"]["mu_star_error"] is None
    assert doc["elements"] == 20 and doc["end_shortening"] == 1e-2
    sp = SpectrumSummary("beam", "asymmetric", 1.0, "U_A", np.array([-4.0, np.nan]))
    doc = _strict(convert.spectrum(sp).model_dump(mode="json"))
    assert doc["sigma2"] == [-4.0, None] and doc["omega"] == [2.0, None]


def test_a_signals_info_holds_typed_results_and_plain_gives_their_documents() -> None:
    """The simulations route stores ``convert.plain(signal.info)``: the Resolution,
    ErrorEstimate and Choice become their wire documents (ErrorEstimate with its total)."""
    from sim import simulate
    from sim.scene import Scene

    sig = simulate(Scene(actuation="asymmetric", mu=0.5, duration=1.0, rtol=0.05), "auto")
    assert isinstance(sig.info["resolution"], Resolution)
    assert isinstance(sig.info["error"], ErrorEstimate)
    info = _strict(convert.plain(dict(sig.info)))
    assert info["error"] == convert.error_estimate(sig.info["error"]).model_dump(mode="json")
    assert info["error"]["total"] == pytest.approx(sig.info["error"].total)
    auto = sim_wire.BackendChoice.model_validate(info["auto"])
    assert auto.model == sig.model
    assert auto.error.total == pytest.approx(sig.info["auto"].estimate.total)


def test_snap_document_is_the_same_for_the_cli_and_the_api(capsys) -> None:  # noqa: ANN001
    from service.api.routers.snaps import run_snap
    from service.schemas.snaps import SnapRequest, SnapResult

    cli = _cli(capsys, "snap", "--actuation", "asymmetric", "--dmu", "0.02", "--model",
               "normal-form", "--duration", "3")  # fmt: skip
    api = run_snap(SnapRequest(model="normal-form", actuation="asymmetric", dmu=0.02,
                               duration=3.0).model_dump())  # fmt: skip
    assert cli == api
    snap = SnapResult.model_validate(api)
    assert snap.samples == len(snap.t) == len(snap.amplitude) and snap.snap_time is not None


def test_atlas_rows_and_summary_go_through_the_converter() -> None:
    from service.atlas import parse_spec, run_atlas

    spec = parse_spec({"kind": "bifurcation", "fixed": {"model": "euler-beam"},
                       "grid": {"actuation": ["asymmetric", "symmetric"]}})  # fmt: skip
    res = run_atlas(spec, serial=True)
    report = _strict(convert.atlas_report(res).model_dump(mode="json"))
    assert [c["results"]["transition"] for c in report["cells"]] == [
        "saddle-node", "subcritical-pitchfork"]  # fmt: skip
    assert report["summary"] == convert.atlas_summary(res.summary).model_dump(mode="json")
    assert report["summary"]["ok"] == 2 and report["summary"]["workers"]


def test_the_demos_beam_summary_is_typed() -> None:
    from service.cli.sim_cmds import beam_summary

    doc = _strict(beam_summary())
    beam = sim_wire.BeamSummary.model_validate(doc)
    assert [b.transition for b in beam.transitions] == [
        "saddle-node", "subcritical-pitchfork", "supercritical-pitchfork"]  # fmt: skip
    assert len(beam.spectrum_U_A) == 15 and beam.impulse_response.samples > 0
    # U_A's fundamental slows down as mu -> mu*
    asym = [abs(p.sigma2[0]) for p in beam.spectrum_U_A if p.actuation == "asymmetric"]
    assert asym == sorted(asym, reverse=True)
