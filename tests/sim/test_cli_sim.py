"""The simulator CLI: one JSON document on stdout, documented keys, one-line errors."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import pytest

from service.cli import main


def run_json(capsys, *argv: str) -> dict:
    assert main([*argv, "--json"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1  # exactly one document
    return json.loads(out)


def test_bifurcation_json(capsys) -> None:
    doc = run_json(capsys, "bifurcation", "--actuation", "symmetric")
    assert {"actuation", "model", "mu_star", "lambda_star", "transition", "secondary"} <= set(doc)
    assert doc["model"] == "euler-beam" and doc["transition"] == "subcritical-pitchfork"
    assert abs(doc["mu_star"] - 2) < 1e-12
    assert doc["secondary"][0]["transition"] == "saddle-node"
    assert abs(doc["secondary"][0]["mu_star"] - 2.0119053042) < 1e-9


def test_equilibria_json(capsys) -> None:
    doc = run_json(capsys, "equilibria", "--actuation", "asymmetric", "--mu", "1.0")
    assert doc["actuation"] == "asymmetric" and doc["mu"] == 1.0
    branches = {e["branch"]: e for e in doc["equilibria"]}
    assert set(branches) == {"U_A", "U_B", "S_A", "S_B", "W_A", "W_B"}
    for e in branches.values():
        assert {"branch", "lambda", "w_half", "w_quarter", "energy", "stable"} <= set(e)
    assert branches["U_A"]["stable"] and not branches["S_B"]["stable"]


def test_spectrum_json_ordered_by_abs_sigma2(capsys) -> None:
    doc = run_json(capsys, "spectrum", "--actuation", "antisymmetric", "--mu", "1.5",
                   "--branch", "U_A", "--modes", "5")  # fmt: skip
    s2 = doc["sigma2"]
    assert len(s2) == 5 and doc["branch"] == "U_A"
    assert [abs(x) for x in s2] == sorted(abs(x) for x in s2)
    assert doc["omega"] == pytest.approx([abs(x) ** 0.5 for x in s2])


def test_normal_form_json(capsys) -> None:
    doc = run_json(capsys, "normal-form", "--actuation", "asymmetric")
    assert doc["transition"] == "saddle-node" and set(doc["coefficients"]) == {"a1", "a2"}
    doc = run_json(capsys, "normal-form", "--actuation", "antisymmetric")
    assert set(doc["coefficients"]) == {"b1", "b2"}


@pytest.mark.parametrize("model", ["euler-beam", "normal-form"])
def test_simulate_writes_csv(capsys, tmp_path, model: str) -> None:
    out = tmp_path / "sig.csv"
    doc = run_json(capsys, "simulate", "--model", model, "--actuation", "asymmetric",
                   "--mu", "1.78", "--snr", "30", "--seed", "3", "--out", str(out))  # fmt: skip
    assert {"path", "samples", "model", "mu"} <= set(doc) and doc["model"] == model
    rows = list(csv.reader(out.open()))
    assert rows[0] == ["t", "w"] and len(rows) == doc["samples"] + 1
    assert float(rows[2][0]) == pytest.approx(doc["dt"])


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["spectrum", "--actuation", "asymmetric", "--mu", "abc"], "--mu"),
        (["spectrum", "--actuation", "sideways", "--mu", "1"], "--actuation"),
        (["spectrum", "--actuation", "asymmetric", "--mu", "1.9"], "mu=1.9"),
        (["spectrum", "--actuation", "asymmetric", "--mu", "1", "--modes", "0"], "--modes"),
        (
            ["simulate", "--actuation", "asymmetric", "--mu", "1", "--dt", "-1", "--out", "x.csv"],
            "dt",
        ),
    ],
)
def test_bad_arguments_give_one_line_error_and_nonzero_exit(argv, needle, tmp_path) -> None:
    proc = subprocess.run([sys.executable, "-c", "import sys; from service.cli import main; "
                           "sys.exit(main(sys.argv[1:]))", *argv],
                          capture_output=True, text=True, cwd=tmp_path)  # fmt: skip
    assert proc.returncode != 0
    assert needle in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stdout == ""


def test_cosserat_through_the_cli(capsys, tmp_path) -> None:
    argv = ["bifurcation", "--model", "cosserat", "--actuation", "asymmetric",
            "--end-shortening", "1e-2", "--slenderness", "1e-3", "--elements", "24"]  # fmt: skip
    doc = run_json(capsys, *argv)
    assert doc["model"] == "cosserat" and doc["elements"] == 24
    assert doc["transition"] == "saddle-node" and abs(doc["mu_star"] - 1.78) < 0.03
    out = tmp_path / "c.csv"
    doc = run_json(capsys, "simulate", "--model", "cosserat", "--actuation", "symmetric",
                   "--mu", "1.0", "--elements", "24", "--end-shortening", "1e-2",
                   "--slenderness", "1e-2", "--out", str(out))  # fmt: skip
    assert doc["model"] == "cosserat" and out.exists()


@pytest.mark.slow
def test_warn_on_the_cosserat_rod(capsys) -> None:
    doc = run_json(capsys, "warn", "--model", "cosserat", "--actuation", "asymmetric",
                   "--elements", "24", "--end-shortening", "1e-2", "--slenderness", "6.3e-3",
                   "--max-measurements", "24", "--seed", "1", "--no-progress")  # fmt: skip
    t = doc["truth"]  # the rod's own mu* (static Hessian), not the beam's
    assert t["max_mu_measured"] < t["mu_star"]
    assert doc["prediction"]["transition"] == "saddle-node"  # the one sweep document
    assert abs(t["error"]) < 1e-5  # measured -9.8e-7 (the paper's rule: -1.3e-5)
