"""The sweep resource as the API and the pages show it: its document and its units.

:func:`sweep_doc` is the one sweep document (``GET /v1/sweeps/{id}``, the listings, a live
sweep's creation and close, the pages); :func:`sweep_units` names the control and time units a
sweep's charts and pages label it with. Both read stored rows only: no numerics here.
"""

from __future__ import annotations

import logging
from typing import Any

from anyio import to_thread
from pydantic import ValidationError

from service import convert, recordings
from service.api.state import AppState, job_doc
from service.api.storage import as_utc
from service.charts import NONDIM
from service.schemas import Sweep

__all__ = ["sweep_doc", "sweep_units"]

log = logging.getLogger("snapwarn.api")


def sweep_doc(sweep: Any, job: Any) -> dict[str, Any]:
    """The sweep resource: the typed sweep document (once succeeded) and its parts."""
    result = None
    if job.status == "succeeded" and job.result:
        try:
            result = convert.sweep_document(job.result)
        except ValidationError:  # a document this version cannot read: the job still shows it
            log.warning("sweep %s: stored result does not read as a sweep document", sweep.id)
    pred = result.prediction if result is not None else None
    alarms = result.alarm if result is not None else []
    doc = Sweep(
        id=sweep.id,
        name=sweep.name,
        status=job.status,
        request=sweep.request,
        job=job_doc(job),
        result=result,
        measurements=result.measurements if result is not None else None,
        classification=pred.classification if pred is not None else None,
        prediction=pred,
        alarm=alarms[-1] if alarms else (pred.alarm if pred is not None else None),
        created_at=as_utc(sweep.created_at),
    )
    return doc.model_dump(mode="json")


async def sweep_units(state: AppState, scope: str | None, sweep: Any) -> dict[str, Any]:
    """The user's control name and unit and the records' time unit (from the sweep request's
    ``control`` where given, else from the stored signals of ``sweep``, read with ``scope``);
    the simulator's non-dimensional scales for a simulated sweep. ``mixed`` names what the
    records disagree on (then a neutral name is used)."""
    req = sweep.request or {}
    if req.get("mode") == "live":
        control = req.get("control") or {}
        from service.api.storage import live as store_live

        def first_unit() -> str | None:  # the sweep's time unit: its first record's
            _, recs = store_live.records_after(state.store, sweep.id, 0, 1)
            return (recs[0].record or {}).get("time_unit") if recs else None

        return {"control_name": control.get("name") or "mu", "control_unit": control.get("unit"),
                "time_unit": await to_thread.run_sync(first_unit), "value_unit": None,
                "mixed": []}  # fmt: skip
    if req.get("simulate") is not None or not req.get("measurements"):
        return {"control_name": "mu", "control_unit": NONDIM, "time_unit": NONDIM,
                "value_unit": NONDIM, "mixed": []}  # fmt: skip
    names, cunits, tunits, vunits = set(), set(), set(), set()

    def rows() -> list[Any]:  # one thread for all the reads
        return [state.store.get_signal_meta(m["signal_id"], scope=scope)
                for m in req["measurements"]]  # fmt: skip

    for row in await to_thread.run_sync(rows):
        if row is None:
            continue
        names.add(row.control_name)
        cunits.add(row.control_unit)
        tunits.add(row.unit)
        vunits.add(row.value_unit)
    given = req.get("control") or {}  # the sweep's own control name and unit come first
    if given.get("name"):
        names = {given["name"]}
    if given.get("unit"):
        cunits = {given["unit"]}
    if len(tunits) > 1 and all(recordings.seconds_per(u) is not None for u in tunits):
        tunits = {"s"}  # the analysis brought every record to seconds (common_time_base)
    mixed = [what for what, s in (("control name", names), ("control unit", cunits),
                                  ("time unit", tunits), ("value unit", vunits))
             if len(s) > 1]  # fmt: skip

    def one(s: set) -> str | None:
        vals = sorted(v for v in s if v)
        return vals[0] if len(vals) == 1 else None

    return {
        "control_name": one(names) or "control",
        "control_unit": one(cunits),
        "time_unit": one(tunits),
        "value_unit": one(vunits),
        "mixed": mixed,
    }
