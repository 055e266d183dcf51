"""``snapwarn atlas SPEC``: many independent cells on dask.distributed, persisted in --out."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from service.cli._common import CliError, add_json_flag, bad, emit


def _progress_bar(enabled: bool, name: str) -> Any:
    if not enabled:
        return None
    from tqdm import tqdm

    state: dict[str, Any] = {"bar": None}

    def cb(done: int, total: int, row: Any) -> None:
        bar = state["bar"]
        if bar is None:
            bar = state["bar"] = tqdm(total=total, initial=done, desc=name, unit="cell",
                                      file=sys.stderr, dynamic_ncols=True)  # fmt: skip
            return
        bar.update(done - bar.n)
        if row is not None:
            r = row.results
            msg = f"{row.status} {row.seconds:.2f}s"
            if r.get("mu_star") is not None:
                msg += f" mu*={r['mu_star']:.6g}"
            bar.set_postfix_str(msg, refresh=True)

    cb.close = lambda: state["bar"] is not None and state["bar"].close()  # type: ignore[attr-defined]
    return cb


def _text(doc: dict[str, Any]) -> str:
    s = doc["summary"]
    lines = [
        f"atlas {s['name']!r} ({s['kind']}): {s['ok']} ok, {s['failed']} failed, "
        f"{s['missing']} missing of {s['cells']} cells ({s['resumed']} resumed); "
        f"{s['wall_s']:.1f} s wall, {s['cell_seconds']:.1f} cell-s on {s['engine']}"
    ]
    varied = doc["varied"]
    cols = ["mu_star", "transition"]
    if s["kind"] != "bifurcation":
        cols = ["mu_star", "error", "covered", "responses", "transition", "paper_error"]
    lines.append("  ".join(f"{c:>14}" for c in [*varied, *cols, "s"]))
    for row in doc["cells"]:
        vals = [row["inputs"].get(v) for v in varied]
        if row["status"] == "ok":
            vals += [row["results"].get(c) for c in cols]
        else:
            vals += [f"failed: {(row['error'] or {}).get('type')}"] + [""] * (len(cols) - 1)
        vals.append(row["seconds"])
        lines.append("  ".join(f"{v:>14.8g}" if isinstance(v, float) else f"{str(v):>14}"
                               for v in vals))  # fmt: skip
    m = s["metrics"]
    lines.append("metrics: " + json.dumps(m))
    return "\n".join(lines)


def _atlas(args: argparse.Namespace) -> int:
    from service import convert
    from service.atlas import EngineError, JsonlSink, SpecError, load_spec, run_atlas
    from service.atlas.charts import write_heatmaps

    try:
        spec = load_spec(args.spec)
    except SpecError as exc:
        raise bad("SPEC", args.spec, f"is not a valid atlas spec: {exc}") from None
    if args.workers is not None and not 1 <= args.workers <= 512:
        raise bad("--workers", args.workers, "must be in [1, 512]")
    chart = spec.chart
    if args.heatmap:
        parts = args.heatmap.split(",")
        if len(parts) != 2 or any(p not in spec.varied for p in parts) or parts[0] == parts[1]:
            raise bad("--heatmap", args.heatmap, f"must be X,Y: two different varied "
                      f"parameters of {list(spec.varied)}")
        chart = (parts[0], parts[1])
    sink = None
    out = Path(args.out) if args.out else None
    if out is not None:
        if out.exists() and not out.is_dir():
            raise bad("--out", args.out, "is not a folder")
        out.mkdir(parents=True, exist_ok=True)
        (out / "spec.json").write_text(json.dumps(spec.to_dict(), indent=2) + "\n")
        sink = JsonlSink(out / "cells.jsonl")
    cb = _progress_bar(not args.no_progress, spec.name)
    try:
        result = run_atlas(spec, scheduler=args.scheduler, workers=args.workers, sink=sink,
                           progress=cb, serial=args.serial)  # fmt: skip
    except EngineError as exc:
        raise bad(f"--{exc.parameter}", exc.value, str(exc)) from None
    finally:
        if cb is not None:
            cb.close()
    doc = convert.atlas_report(result).model_dump(mode="json")
    if out is not None:
        (out / "summary.json").write_text(json.dumps(doc["summary"], indent=2) + "\n")
        if chart is not None and result.rows:
            files = write_heatmaps(result, chart[0], chart[1], out)
            if not args.json:
                sys.stderr.write("heatmaps: " + ", ".join(str(f) for f in files) + "\n")
    emit(doc, json_mode=args.json, text=_text(doc))
    return 0 if not result.missing else 3


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``atlas`` to ``sub``."""
    p = sub.add_parser(
        "atlas",
        help="a grid of independent cells (bifurcation, warn, sweep) on dask.distributed",
        description="Run an atlas SPEC (JSON or YAML) on an embedded LocalCluster or on a "
        "running dask scheduler. With --out, each finished cell is appended to "
        "OUT/cells.jsonl at once, so a rerun skips the finished cells; heatmaps (PNG + CSV) "
        "and summary.json are written there at the end. Exit status 3 when cells are "
        "missing (time bound or lost workers): run it again.",
    )
    p.add_argument("spec", metavar="SPEC", help="atlas spec (.json, .yaml)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="dask scheduler, e.g. tcp://10.0.0.5:8786 (default: "
                        "$SNAPWARN_DASK_SCHEDULER, else a LocalCluster)")  # fmt: skip
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the LocalCluster (default: the usable CPUs)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="folder of cells.jsonl, summary.json and the heatmaps")
    p.add_argument("--heatmap", default=None, metavar="X,Y",
                   help="the heatmaps' axes (default: the spec's chart, else its first two)")
    p.add_argument("--serial", action="store_true", help="plain loop in this process (no dask)")
    p.add_argument("--no-progress", action="store_true")
    add_json_flag(p)
    p.set_defaults(func=_atlas)


__all__ = ["CliError", "register"]
