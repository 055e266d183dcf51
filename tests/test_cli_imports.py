"""The command line imports only what the command it runs needs: ``snapwarn --help`` loads no
numpy, pydantic or numerics; ``detect`` and ``predict`` load no web stack, no charts, no dask
(and detect no scipy.signal/stats). Checked in a fresh interpreter (``sys.modules``), not
timed; the vocabulary the parser carries equals its owners'."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

_PROBE = """
import json, sys
from service.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
sys.stdout.flush()
sys.stderr.write("\\nMODULES " + json.dumps(sorted(sys.modules)) + "\\n")
"""

WEB_AND_CHARTS = ("fastapi", "starlette", "uvicorn", "sqlalchemy", "matplotlib", "dask",
                  "distributed", "httpx2", "jinja2", "alembic")  # fmt: skip


def _loaded(*argv: str) -> set[str]:
    r = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True,
                       timeout=600)  # fmt: skip
    line = [s for s in r.stderr.splitlines() if s.startswith("MODULES ")]
    assert line, r.stderr
    return {m.split(".")[0] for m in json.loads(line[-1][8:])} | set(json.loads(line[-1][8:]))


def _absent(loaded: set[str], names: tuple[str, ...]) -> list[str]:
    return [n for n in names if n in loaded]


def test_help_imports_no_numerics() -> None:
    loaded = _loaded("--help")
    assert "service.cli.analysis_cmds" in loaded  # the probe did build the whole parser
    assert _absent(loaded, ("numpy", "scipy", "numba", "pydantic", *WEB_AND_CHARTS)) == []


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:  # noqa: ANN001
    d = tmp_path_factory.mktemp("cli-imports")
    t = np.arange(2000) * 0.01
    w = 0.2 + np.exp(-0.1 * t) * np.cos(6 * t) + 1e-3 * np.random.default_rng(0).normal(size=t.size)
    rec = d / "r.csv"
    np.savetxt(rec, np.c_[t, w], delimiter=",", header="t,w", comments="")
    mu = np.linspace(0.0, 1.6, 8)
    table = d / "t.csv"
    np.savetxt(table, np.c_[mu, -np.sqrt(2.0 - mu)], delimiter=",", header="mu,sigma2",
               comments="")  # fmt: skip
    return {"record": rec, "table": table}


def test_detect_imports_no_web_stack_no_charts(files: dict[str, Path]) -> None:
    loaded = _loaded("detect", str(files["record"]), "--json")
    assert "service.analysis.detect" in loaded  # it did detect
    assert _absent(loaded, (*WEB_AND_CHARTS, "scipy.signal", "scipy.stats")) == []


def test_plain_detect_imports_no_wire_models_and_no_scipy_modules(files: dict[str, Path]) -> None:
    """The line alone needs no pydantic (~0.3 s CPU) and the detector no scipy submodule (each
    ~0.2 s: its array-API layer parses docstrings at import)."""
    loaded = _loaded("detect", str(files["record"]))
    assert "service.analysis.detect" in loaded
    assert _absent(loaded, ("pydantic", "service.convert", "scipy.fft", "scipy.ndimage",
                            "scipy.linalg", "scipy.special")) == []  # fmt: skip
    # nor scipy and yaml themselves: numba's __init__ imports them for a version check and an
    # optional config file only (service.analysis._numba_load.import_numba keeps them out)
    assert _absent(loaded, ("scipy", "yaml")) == []


def test_predict_imports_no_web_stack_no_charts(files: dict[str, Path]) -> None:
    loaded = _loaded("predict", str(files["table"]), "--json")
    assert "service.analysis.predict" in loaded
    assert _absent(loaded, (*WEB_AND_CHARTS, "scipy.stats")) == []  # stats: ~0.25 s CPU


def test_plain_predict_imports_no_wire_models_and_prints_the_wires_line(
    files: dict[str, Path], capsys: pytest.CaptureFixture
) -> None:
    """The line alone needs no pydantic; it is the line the wire document gives."""
    from service.cli import main

    loaded = _loaded("predict", str(files["table"]))
    assert "service.analysis.predict" in loaded
    assert _absent(loaded, ("pydantic", "service.convert", "service.schemas")) == []
    assert main(["predict", str(files["table"])]) == 0
    line = capsys.readouterr().out.strip()
    assert main(["predict", str(files["table"]), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    lo, hi = doc["mu_star_interval"]
    assert line == f"{doc['transition']}: mu* = {doc['mu_star']} (95%: [{lo}, {hi}])"


def test_the_parsers_vocabulary_is_its_owners() -> None:
    from service.cli import _vocab
    from service.recordings import FORMATS
    from service.schemas.predictions import PREDICT_TRANSITIONS
    from sim.backends import BACKENDS
    from sim.scene import ACTUATIONS, BRANCHES, MODELS

    assert _vocab.ACTUATIONS == ACTUATIONS
    assert _vocab.BRANCHES == BRANCHES
    assert _vocab.MODELS == MODELS
    assert _vocab.STATIC_MODELS == tuple(BACKENDS)
    assert _vocab.PREDICT_TRANSITIONS == PREDICT_TRANSITIONS
    assert _vocab.RECORDING_FORMATS == FORMATS


def test_each_commands_module_is_the_one_that_registers_it() -> None:
    """``service.cli.COMMANDS`` (a command's run builds only its module's parser) names, for
    every command, the module whose ``register`` adds it, and no module adds another."""
    import argparse
    import importlib

    from service import cli

    found: dict[str, str] = {}
    for name in cli._MODULES:
        sub = argparse.ArgumentParser().add_subparsers()
        importlib.import_module(f"service.cli.{name}").register(sub)
        found.update(dict.fromkeys(sub.choices, name))
    assert found == cli.COMMANDS


def test_a_commands_run_builds_only_its_modules_parser(files: dict[str, Path]) -> None:
    loaded = _loaded("detect", str(files["record"]))
    assert _absent(loaded, ("service.cli.sim_cmds", "service.cli.service_cmds",
                            "service.cli.atlas_cmds", "service.cli.watch_cmds")) == []  # fmt: skip


_THREADS = """
import json, os, sys
from service.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
sys.stderr.write("\\nENV " + json.dumps({v: os.environ.get(v) for v in
    ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}) + "\\n")
"""


def _env_after(*argv: str, **env: str) -> dict:
    import os

    r = subprocess.run([sys.executable, "-c", _THREADS, *argv], capture_output=True, text=True,
                       timeout=600, env={k: v for k, v in os.environ.items()
                                         if not k.endswith("_NUM_THREADS")} | env)  # fmt: skip
    line = [s for s in r.stderr.splitlines() if s.startswith("ENV ")]
    assert line, r.stderr
    return json.loads(line[-1][4:])


def test_detect_runs_one_blas_thread_as_the_api_workers_unless_the_user_says(
    files: dict[str, Path],
) -> None:
    """As the API's analysis workers (service.api.executor), unless the user set it."""
    assert _env_after("detect", str(files["record"])) == dict.fromkeys(
        ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"), "1")
    assert _env_after("detect", str(files["record"]), OPENBLAS_NUM_THREADS="2")[
        "OPENBLAS_NUM_THREADS"] == "2"
    assert _env_after("--help")["OPENBLAS_NUM_THREADS"] is None


def test_detect_and_predict_run_with_the_cyclic_collector_paused_and_restore_it(
    files: dict[str, Path], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """Paused while the command runs, enabled again when it returns (also on an error);
    other commands leave it alone; the answer is the same line as with it running."""
    import gc

    from service.analysis import detect as detect_pkg
    from service.cli import _main, main

    seen: list[bool] = []
    real = detect_pkg.detect

    def spy(*a, **k):  # noqa: ANN002, ANN003, ANN202
        seen.append(gc.isenabled())
        return real(*a, **k)

    assert gc.isenabled()
    assert _main(["detect", str(files["record"])]) == 0  # the collector running throughout
    running_line = capsys.readouterr().out
    monkeypatch.setattr(detect_pkg, "detect", spy)
    assert main(["detect", str(files["record"])]) == 0
    assert seen == [False] and gc.isenabled()
    assert capsys.readouterr().out == running_line
    assert main(["detect", str(files["record"].parent / "missing.csv")]) == 2
    assert gc.isenabled()
    assert main(["predict", str(files["table"])]) == 0
    assert gc.isenabled()
    gc.disable()  # a caller's own setting is kept
    try:
        assert main(["detect", str(files["record"])]) == 0
        assert not gc.isenabled()
    finally:
        gc.enable()
    capsys.readouterr()


_FREEZE = """
import gc, json, sys
from service.cli import main
sys.argv = ["snapwarn", *sys.argv[1:]]
rc = main()
sys.stdout.flush()
sys.stderr.write("GC " + json.dumps([rc, gc.isenabled(), gc.get_freeze_count() > 0]) + "\\n")
"""


def test_run_as_the_program_the_objects_left_are_frozen_before_the_collector_resumes(
    files: dict[str, Path],
) -> None:
    """main() with argv from sys.argv (the console script): the objects alive at the end are
    frozen (the exit's collection does not walk them again), the collector is on; the same line
    is printed as with an explicit argv (which freezes nothing: test above)."""
    r = subprocess.run([sys.executable, "-c", _FREEZE, "detect", str(files["record"])],
                       capture_output=True, text=True, timeout=600)  # fmt: skip
    line = [s for s in r.stderr.splitlines() if s.startswith("GC ")]
    assert line, r.stderr
    assert json.loads(line[-1][3:]) == [0, True, True]
    code = "import sys; from service.cli import main; main(sys.argv[1:])"
    plain = subprocess.run([sys.executable, "-c", code, "detect", str(files["record"])],
                           capture_output=True, text=True, timeout=600)  # fmt: skip
    assert r.stdout == plain.stdout and r.stdout.startswith("fundamental: ")
