"""Heatmap pooling over the other axes (seeds...), and the files written per result."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.atlas import CellResult
from service.atlas.charts import heatmap, write_heatmaps
from service.atlas.results import AtlasResult, summarise


def _row(i: int, damping: float, snr: float, seed: int, err: float, covered: bool,
         transition: str) -> CellResult:  # fmt: skip
    return CellResult(key=f"k{i}", index=i, status="ok", worker="w", seconds=1.0,
                      inputs={"damping": damping, "snr_db": snr, "seed": seed},
                      results={"error": err, "covered": covered, "transition": transition,
                               "responses": 10 + seed, "abs_error": abs(err),
                               "paper_error": 10 * err, "mu_star": 1.78 + err})  # fmt: skip


ROWS = [
    _row(0, 2e-4, 40, 1, -1e-6, True, "saddle-node"),
    _row(1, 2e-4, 40, 2, 3e-6, True, "saddle-node"),
    _row(2, 2e-4, 40, 3, -2e-6, False, "pitchfork"),
    _row(3, 2e-3, 40, 1, 1e-4, False, "saddle-node"),
    _row(4, 2e-4, 20, 1, 5e-5, True, "saddle-node"),
    CellResult(key="k5", index=5, status="failed", inputs={"damping": 2e-3, "snr_db": 20,
               "seed": 1}, error={"type": "SimulationError", "message": "x"}),  # fmt: skip
]


def test_pooling_over_the_seeds() -> None:
    cov = heatmap(ROWS, "damping", "snr_db", "coverage")
    assert cov.xs == (2e-4, 2e-3) and cov.ys == (20, 40)
    assert cov.values[1][0] == pytest.approx(2 / 3) and cov.counts[1][0] == 3
    assert cov.values[1][1] == 0.0 and cov.values[0][1] is None  # failed cell: no value
    err = heatmap(ROWS, "damping", "snr_db", "error")
    assert err.values[1][0] == pytest.approx(2e-6)  # median of |-1e-6|, |3e-6|, |-2e-6|
    kind = heatmap(ROWS, "damping", "snr_db", "type")
    assert kind.values[1][0] == "saddle-node"
    assert heatmap(ROWS, "damping", "snr_db", "responses").values[1][0] == pytest.approx(12.0)


def test_warn_heatmaps_and_summary(tmp_path: Path) -> None:
    s = summarise("t", "warn", 6, ROWS, resumed=0, wall_s=1.0, engine="serial")
    assert (s.ok, s.failed, s.missing) == (5, 1, 0)
    assert s.metrics["coverage"] == pytest.approx(3 / 5)
    assert s.metrics["median_abs_error"] == pytest.approx(3e-6)
    res = AtlasResult("t", "warn", ("damping", "snr_db", "seed"), tuple(ROWS), s)
    files = write_heatmaps(res, "damping", "snr_db", tmp_path)
    names = {f.name for f in files}
    assert {"heatmap-error.png", "heatmap-coverage.csv", "heatmap-type.png",
            "heatmap-responses.csv", "heatmap-paper_error.png"} <= names
    assert (tmp_path / "heatmap-coverage.csv").read_text().splitlines()[0] == (
        "snr_db \\ damping,0.0002,0.002")
