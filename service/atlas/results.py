"""An atlas's outcome: one :class:`CellResult` per cell and a summary over them."""

from __future__ import annotations

import statistics
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from service.atlas.cells import CellResult


@dataclass(frozen=True)
class AtlasSummary:
    """Counts, cost and the kind's headline numbers.

    Attributes
    ----------
    cells : int
        Cells in the spec.
    ok, failed, missing : int
        Cells that succeeded, failed (their error is data) and that are not done (the atlas
        hit its time bound or lost a cell more often than the scheduler allows: a rerun
        computes them).
    resumed : int
        Cells read back from an earlier run (not computed again).
    wall_s : float
        Wall time of this run (s).
    cell_seconds, cpu_seconds : float
        Sum of the cells' wall and CPU times (s), this run's and the resumed ones.
    cell_seconds_median : float or None
        Median wall time of one cell (s).
    workers : tuple of str
        Distinct workers that computed cells.
    engine : str
        "dask" (with the scheduler's address) or "serial".
    metrics : dict
        bifurcation: ``mu_star_min``, ``mu_star_max``, ``transitions`` (counts).
        warn / sweep: ``median_abs_error``, ``coverage`` (fraction of cells whose 95 %
        interval holds the true mu*), ``mean_responses``, ``transition_correct`` (fraction),
        ``paper_median_abs_error`` and ``better_than_paper`` (fraction of cells where the
        prediction's error is at most the paper's rule's on the same data).
    """

    name: str
    kind: str
    cells: int
    ok: int
    failed: int
    missing: int
    resumed: int
    wall_s: float
    cell_seconds: float
    cpu_seconds: float
    cell_seconds_median: float | None
    workers: tuple[str, ...]
    engine: str
    metrics: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class AtlasResult:
    """The rows (ordered by the spec's cell index) and the summary."""

    name: str
    kind: str
    varied: tuple[str, ...]
    rows: tuple[CellResult, ...]
    summary: AtlasSummary
    missing: tuple[str, ...] = ()


def _median(xs: Sequence[float]) -> float | None:
    return float(statistics.median(xs)) if xs else None


def _frac(xs: Sequence[Any]) -> float | None:
    vals = [bool(x) for x in xs if x is not None]
    return sum(vals) / len(vals) if vals else None


def kind_metrics(kind: str, rows: Sequence[CellResult]) -> dict[str, Any]:
    """The kind's headline numbers over the successful rows (see :class:`AtlasSummary`)."""
    ok = [r.results for r in rows if r.status == "ok"]
    if kind == "bifurcation":
        mus = [r["mu_star"] for r in ok if r.get("mu_star") is not None]
        return {"mu_star_min": min(mus) if mus else None, "mu_star_max": max(mus) if mus else None,
                "transitions": dict(Counter(r.get("transition") for r in ok))}  # fmt: skip
    errs = [r["abs_error"] for r in ok if r.get("abs_error") is not None]
    perr = [abs(r["paper_error"]) for r in ok if r.get("paper_error") is not None]
    resp = [r["responses"] for r in ok if r.get("responses") is not None]
    return {
        "median_abs_error": _median(errs),
        "coverage": _frac([r.get("covered") for r in ok]),
        "mean_responses": sum(resp) / len(resp) if resp else None,
        "transition_correct": _frac([r.get("transition_correct") for r in ok]),
        "paper_median_abs_error": _median(perr),
        "better_than_paper": _frac([r.get("better_than_paper") for r in ok]),
        "transitions": dict(Counter(r.get("transition") for r in ok)),
    }


def summarise(name: str, kind: str, total: int, rows: Sequence[CellResult], *, resumed: int,
              wall_s: float, engine: str) -> AtlasSummary:  # fmt: skip
    """Build the summary of ``rows`` (one per finished cell) of an atlas of ``total`` cells."""
    secs = [r.seconds for r in rows]
    return AtlasSummary(
        name=name, kind=kind, cells=total,
        ok=sum(r.status == "ok" for r in rows), failed=sum(r.status == "failed" for r in rows),
        missing=total - len(rows), resumed=resumed, wall_s=wall_s, cell_seconds=sum(secs),
        cpu_seconds=sum(r.cpu_seconds for r in rows), cell_seconds_median=_median(secs),
        workers=tuple(sorted({r.worker for r in rows})), engine=engine,
        metrics=kind_metrics(kind, rows),
    )  # fmt: skip
