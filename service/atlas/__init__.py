"""Atlases: many independent cells (bifurcation, warn, sweep) on dask.distributed.

>>> from service.atlas import load_spec, run_atlas       # doctest: +SKIP
>>> result = run_atlas(load_spec("examples/atlas-cosserat-3x3.yaml"))
>>> result.summary.ok, [r.results["mu_star"] for r in result.rows]

Numerics-side orchestration: no web framework, no database. The spec (:mod:`.spec`), the
kinds of cells (:mod:`.cells`), the engine and its sinks (:mod:`.engine`), the results
(:mod:`.results`) and the heatmaps (:mod:`.charts`).
"""

from service.atlas.cells import KINDS, CellResult, run_cell
from service.atlas.engine import (
    SCHEDULER_ENV,
    CellSink,
    EngineError,
    JsonlSink,
    MemorySink,
    dask_client,
    run_atlas,
    scheduler_address,
)
from service.atlas.results import AtlasResult, AtlasSummary
from service.atlas.spec import AtlasSpec, Cell, SpecError, cell_key, load_spec, parse_spec

__all__ = [
    "KINDS", "SCHEDULER_ENV", "AtlasResult", "AtlasSpec", "AtlasSummary", "Cell", "CellResult",
    "CellSink", "EngineError", "JsonlSink", "MemorySink", "SpecError", "cell_key",
    "dask_client", "load_spec", "parse_spec", "run_atlas", "run_cell", "scheduler_address",
]
