"""Wire models of atlases: many independent cells (bifurcation, warn, sweep) and a summary.

``snapwarn atlas SPEC --json`` prints an :class:`AtlasReport`; ``/v1/atlases`` answers
:class:`Atlas` (the resource and its job) and pages of :class:`AtlasCell`. The spec itself is
validated by ``service.atlas.spec.parse_spec`` (every error names the field and the value);
:class:`AtlasSpecDoc` only gives it a shape for the OpenAPI document.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.schemas.common import Integer, Number
from service.schemas.jobs import Job

AtlasKind = Literal["bifurcation", "warn", "sweep"]
AtlasMetric = Literal["mu_star", "type", "error", "coverage", "responses", "paper_error"]


class AtlasRange(BaseModel):
    """An axis as a range: ``num`` values from ``from`` to ``to`` (linear or log spaced)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    from_: Number = Field(alias="from")
    to: Number
    num: Integer = Field(ge=1)
    scale: Literal["linear", "log"] = "linear"


class AtlasChart(BaseModel):
    """The heatmap's axes: two of the varied parameters."""

    model_config = ConfigDict(extra="forbid")

    x: str
    y: str


class AtlasSpecDoc(BaseModel):
    """An atlas spec: a ``grid`` (product of axes) or a list of ``cells``, over the kind's
    parameters; ``fixed`` holds those common to all cells.

    bifurcation: actuation, model (euler-beam | cosserat), end_shortening, slenderness,
    elements, clamp. warn: actuation, model, damping, snr_db, seed, max_measurements, kick,
    end_shortening, slenderness, elements. sweep (CLI only: manifests are files): manifest,
    method, mu_star_true, transition_true.
    """

    model_config = ConfigDict(extra="forbid")

    kind: AtlasKind
    name: str | None = Field(default=None, max_length=200)
    fixed: dict[str, Any] = Field(default_factory=dict)
    grid: dict[str, list[Any] | AtlasRange] | None = None
    cells: list[dict[str, Any]] | None = None
    chart: AtlasChart | None = None
    retries: Integer = Field(default=2, ge=0, le=10)
    timeout_s: Number | None = Field(default=None, gt=0, description="Bound on the wall time.")


class AtlasRequest(BaseModel):
    """``POST /v1/atlases``: a spec and an optional name."""

    model_config = ConfigDict(extra="forbid")

    spec: AtlasSpecDoc
    name: str | None = Field(default=None, max_length=500)


class AtlasFlag(BaseModel):
    code: str
    message: str


class AtlasCellError(BaseModel):
    """Why a cell failed: the exception's type, the parameter and value it names."""

    type: str
    parameter: str | None = None
    value: Any = None
    message: str


Scalar = float | int | bool | str | None
"""A cell's result value: a number (null when missing or not finite), a flag or a name."""


class AtlasCell(BaseModel):
    """One row: the cell's inputs, results, flags, time and worker."""

    key: str = Field(description="Stable hash of the kind and the complete inputs.")
    index: int
    inputs: dict[str, Any]
    status: Literal["ok", "failed"]
    results: dict[str, Scalar] = Field(
        default_factory=dict,
        description="Flat scalar results of the kind (empty for a failed cell). bifurcation: "
        "mu_star, lambda_star, secondary_mu_star, mu_star_error (units of mu; Lambda for "
        "lambda_star), transition, elements, newton_solves. warn and sweep: mu_star, "
        "mu_star_lo, mu_star_hi (the 95 % interval), mu_star_true, error, abs_error, "
        "paper_mu_star, paper_error (units of the control), transition, transition_true, "
        "transition_correct, covered, better_than_paper, a, responses, stopped.",
    )
    flags: list[AtlasFlag] = Field(default_factory=list)
    error: AtlasCellError | None = None
    seconds: float = Field(description="Wall time of the computation in its worker (s).")
    cpu_seconds: float = Field(default=0.0, description="CPU time of the worker process "
                               "during the computation (s).")
    worker: str = ""


class AtlasSummary(BaseModel):
    """Counts, cost and the kind's headline numbers (see ``service.atlas.AtlasSummary``)."""

    name: str
    kind: AtlasKind
    cells: int = Field(description="Cells in the spec.")
    ok: int = Field(description="Cells computed.")
    failed: int = Field(description="Cells whose computation raised (see their error).")
    missing: int = Field(description="Cells not done (time bound or lost workers).")
    resumed: int = Field(description="Cells taken from an earlier run (not recomputed).")
    wall_s: float = Field(description="Wall time of the run, s.")
    cell_seconds: float = Field(description="Sum of the cells' wall times in their workers, s.")
    cpu_seconds: float = Field(description="Sum of the cells' CPU times, s.")
    cell_seconds_median: float | None = Field(default=None, description="Median cell wall "
                                              "time, s (null without cells).")
    workers: list[str] = Field(default_factory=list, description="Workers that computed cells.")
    engine: str = Field(description="Where the cells ran: the dask cluster, 'serial', or "
                        "'none (all cells resumed)'.")
    metrics: dict[str, Scalar | dict[str, int]] = Field(
        default_factory=dict,
        description="The kind's headline numbers over the successful cells. bifurcation: "
        "mu_star_min, mu_star_max, transitions (count per type). warn and sweep: "
        "median_abs_error, paper_median_abs_error (units of the control), coverage, "
        "transition_correct, better_than_paper (fractions of cells), mean_responses, "
        "transitions.",
    )


class AtlasReport(BaseModel):
    """``snapwarn atlas --json``: the summary and one row per finished cell."""

    name: str
    kind: AtlasKind
    varied: list[str]
    summary: AtlasSummary
    cells: list[AtlasCell]
    missing: list[str] = Field(default_factory=list, description="Keys of cells not done.")


class Atlas(BaseModel):
    """An atlas resource: its spec, its job, the cells done so far, the summary once done."""

    id: str
    name: str | None = None
    kind: AtlasKind
    status: str
    spec: dict[str, Any]
    cells_total: int
    cells_done: int
    job: Job
    summary: AtlasSummary | None = None
    created_at: datetime


class AtlasPage(BaseModel):
    items: list[Atlas]
    total: int
    limit: int
    offset: int


class AtlasCellPage(BaseModel):
    items: list[AtlasCell]
    total: int
    limit: int
    offset: int
