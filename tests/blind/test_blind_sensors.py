"""Sensors as labs wire them: an AC-coupled accelerometer and a logger that writes two sensors
into one CSV, through the CLI, HTTP (SDK over a real uvicorn) and a live sweep.

- AC coupling (``_blind_recorder.Recording.highpass_hz``): an IEPE accelerometer's first-order
  high-pass at 2 Hz while the arch's last records ring at 2.1 Hz. The filter is linear, so the
  structure's poles (the truth) are unchanged; it adds a real pole at ``-2 pi f_c``.
- Two sensors in one file: ``t [s], disp [mm], acc [g]`` (the signal column by its name), and
  ``ch1 [g], ch2 [mm]`` (no name says which: the product must refuse and name the columns).

Slow (each sweep ~1 min of CPU).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

import _blind_sweeps as S  # noqa: E402
import _blind_trials as T  # noqa: E402

pytestmark = pytest.mark.slow

AC = {"sensor": "accel", "unit": "g", "highpass_hz": 2.0}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory):
    s = T.Server(tmp_path_factory.mktemp("blind-sensors-serve"))
    yield s
    s.stop()


def test_an_ac_coupled_accelerometer_sweep_through_the_cli_http_and_live(server, tmp_path: Path):
    """arch_fold lab seed 21 (fold at 96.75844 N), 2 Hz AC coupling: saddle-node [96.7534,
    96.8674] on main 859fac3 (right, covered); the doors agree to 1e-9."""
    truth = S.campaign("arch_fold", "lab", 21, **AC).write(tmp_path / "c")
    cli = T.cli_sweep(truth.manifest)
    assert not T.failures(cli, truth), T.describe(truth, cli, T.judge(cli, truth))
    http = T.http_sweep(server.url, truth.manifest, truth.control_unit)
    assert http.ok, http.error
    assert http.transition == cli.transition
    assert http.mu_star == pytest.approx(cli.mu_star, rel=1e-9)
    assert np.allclose(http.interval, cli.interval, rtol=1e-9)
    T.assert_live_gives(server.url, truth, cli, "blind AC-coupled accelerometer")
    assert not server.server_errors()


@pytest.mark.xfail(strict=True, reason=(
    "detector (measured on main 859fac3): rec03 (88.81 N, a stable record ringing at 5.67 Hz "
    "behind a 2 Hz AC coupling) read alone by `snapwarn detect`: the fundamental is an "
    "overdamped 'mode' sigma2 -27.1 +- 38 with a pole GROWING at +10.16/s (the filter's real "
    "pole is at -12.57/s), flag `unstable` ('the equilibrium is unstable (past the "
    "transition)'), after a false `repeated_kick` at t = 2.148 s (one hit) cuts the window to "
    "1.18 periods; the true mode is listed second (-1270.6 for -1262.7). The sweep sets the "
    "record aside by name."))
def test_an_ac_coupled_record_alone_is_not_read_as_growing(tmp_path: Path):
    truth = S.campaign("arch_fold", "lab", 21, **AC).write(tmp_path / "c")
    name = truth.names[3]
    doc = T.cli_detect(truth.manifest.parent / name)
    codes = {f["code"] for f in doc["flags"]}
    exact = truth.sigma2[3]
    got = doc["fundamental"]["sigma2"]
    assert "unstable" not in codes and "repeated_kick" not in codes, (name, sorted(codes), got)
    assert abs(got - exact) < 0.01 * abs(exact), (name, got, exact)


def _two_sensor_file(folder: Path, names: tuple[str, str]) -> tuple[Path, float]:
    """One record of arch_fold lab seed 21 written by a logger with a laser (mm) and an
    accelerometer (g) on the same clock: ``t [s], names[0], names[1]`` (disp first when the
    first name says mm). Returns the file and the critical mode's exact sigma2."""
    lz = S.campaign("arch_fold", "lab", 21, unit="mm").write(folder / "laser")
    S.campaign("arch_fold", "lab", 21, sensor="accel", unit="g").write(folder / "accel")
    name = lz.names[5]
    a = np.genfromtxt(folder / "laser" / name, delimiter=",", skip_header=1)
    b = np.genfromtxt(folder / "accel" / name, delimiter=",", skip_header=1)
    assert np.array_equal(a[:, 0], b[:, 0])
    first, second = (a[:, 1], b[:, 1]) if "mm" in names[0] else (b[:, 1], a[:, 1])
    path = folder / f"two_{name}"
    with open(path, "w") as fh:
        fh.write(f"t [s],{names[0]},{names[1]}\n")
        for t, y1, y2 in zip(a[:, 0], first, second, strict=True):
            fh.write(f"{t:.9f},{float(y1)!r},{float(y2)!r}\n")
    return path, lz.sigma2[5]


def test_a_two_sensor_csv_is_read_on_its_named_column_or_refused(server, tmp_path: Path):
    """``disp [mm]`` beside ``acc [g]`` (either order): the displacement is read (CLI and an
    upload's detection agree); ``ch1 [g]``/``ch2 [mm]``: refused naming both columns (CLI exit 2,
    HTTP 4xx), never a guess."""
    from service.client import Client
    from service.client.errors import ApiError

    for order in (("disp [mm]", "acc [g]"), ("acc [g]", "disp [mm]")):
        path, exact = _two_sensor_file(tmp_path / order[0][:3], order)
        doc = T.cli_detect(path)
        assert doc["quantity"] == "displacement", doc.get("quantity")
        got = doc["fundamental"]["sigma2"]
        assert abs(got - exact) < 0.01 * abs(exact), (order, got, exact)
        with Client(server.url, timeout=600.0) as sdk:
            sig = sdk.upload_file(path)
            det = sdk.detect(sig.id).model_dump(mode="json")
        assert det["fundamental"]["sigma2"] == pytest.approx(got, rel=1e-9)
    path, _ = _two_sensor_file(tmp_path / "ch", ("ch1 [g]", "ch2 [mm]"))
    r = T.cli_detect(path, expect_error=True)
    assert "ch1 [g]" in r and "ch2 [mm]" in r and "column" in r, r
    with Client(server.url, timeout=600.0) as sdk, pytest.raises(ApiError) as err:
        sdk.upload_file(path)
    assert "ch1" in str(err.value), str(err.value)[:300]
    assert not server.server_errors()
