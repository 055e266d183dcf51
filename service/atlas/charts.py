"""Atlas heatmaps: one result (mu*, type, error, coverage, ...) over two chosen parameters.

Cells that share the same (x, y) values (e.g. several seeds or a third axis) are pooled:
mu* and the responses by their mean, the error by the median of |error|, the coverage as the
fraction of cells whose 95 % interval holds the true mu*, the type by its most frequent value.
Each heatmap is written as a PNG (matplotlib, Agg) and a CSV matrix (rows: y, columns: x),
labelled with the user's parameter names.
"""

from __future__ import annotations

import csv
import statistics
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from service.atlas.cells import KINDS, CellResult

METRICS = {
    "mu_star": ("mu*", "mean"),
    "type": ("transition", "mode"),
    "error": ("|mu* error|", "median_abs"),
    "coverage": ("coverage of the 95 % interval", "fraction"),
    "responses": ("impulse responses used", "mean"),
    "paper_error": ("|mu* error| of the paper's rule", "median_abs"),
}
_FIELD = {"mu_star": "mu_star", "type": "transition", "error": "error", "coverage": "covered",
          "responses": "responses", "paper_error": "paper_error"}  # fmt: skip


@dataclass(frozen=True)
class Heatmap:
    """A metric over two parameters.

    Attributes
    ----------
    metric, x, y : str
    xs, ys : tuple
        The parameters' values (columns, rows).
    values : tuple of tuple
        ``values[i][j]`` at (ys[i], xs[j]): float, category string, or None (no cell).
    counts : tuple of tuple of int
        Cells pooled into each entry.
    """

    metric: str
    x: str
    y: str
    xs: tuple[Any, ...]
    ys: tuple[Any, ...]
    values: tuple[tuple[Any, ...], ...]
    counts: tuple[tuple[int, ...], ...]


def _axis(rows: Sequence[CellResult], name: str) -> tuple[Any, ...]:
    vals: list[Any] = []
    for r in rows:
        v = r.inputs.get(name)
        if v not in vals:
            vals.append(v)
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
        return tuple(sorted(vals))
    return tuple(vals)  # categories in the spec's order (rows come in cell order)


def _pool(how: str, vals: list[Any]) -> Any:
    vals = [v for v in vals if v is not None]
    if not vals:
        return None
    if how == "mode":
        return Counter(vals).most_common(1)[0][0]
    if how == "fraction":
        return sum(bool(v) for v in vals) / len(vals)
    if how == "median_abs":
        return float(statistics.median(abs(float(v)) for v in vals))
    return float(sum(float(v) for v in vals) / len(vals))


def heatmap(rows: Sequence[CellResult], x: str, y: str, metric: str) -> Heatmap:
    """Pool the successful ``rows`` on the (x, y) grid of their inputs (see the module doc)."""
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {list(METRICS)}, got {metric!r}")
    ok = [r for r in rows if r.status == "ok"]
    xs, ys = _axis(ok, x), _axis(ok, y)
    field, how = _FIELD[metric], METRICS[metric][1]
    vals, counts = [], []
    for yv in ys:
        vrow, crow = [], []
        for xv in xs:
            pool = [r.results.get(field) for r in ok
                    if r.inputs.get(x) == xv and r.inputs.get(y) == yv]  # fmt: skip
            vrow.append(_pool(how, pool))
            crow.append(len(pool))
        vals.append(tuple(vrow))
        counts.append(tuple(crow))
    return Heatmap(metric, x, y, xs, ys, tuple(vals), tuple(counts))


def _label(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def write_csv(hm: Heatmap, path: Path) -> Path:
    """The matrix: header ``y \\ x, x1, x2, ...``; one row per y value; empty where no cell."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"{hm.y} \\ {hm.x}", *hm.xs])
        for yv, row in zip(hm.ys, hm.values):
            w.writerow([yv, *("" if v is None else v for v in row)])
    return path


def render_png(hm: Heatmap, path: Path, *, title: str = "") -> Path:
    """The heatmap as a PNG (categorical colours for the type, log colour for errors)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.colors import ListedColormap, LogNorm
    from matplotlib.patches import Patch
    from matplotlib.patheffects import withStroke

    ny, nx = len(hm.ys), len(hm.xs)
    fig, ax = plt.subplots(figsize=(max(4.5, 0.9 * nx + 2.5), max(3.0, 0.5 * ny + 1.8)))
    name, how = METRICS[hm.metric]
    if how == "mode":
        cats = sorted({v for row in hm.values for v in row if v is not None})
        idx = {c: i for i, c in enumerate(cats)}
        grid = np.array([[idx[v] if v is not None else np.nan for v in row] for row in hm.values])
        cmap = ListedColormap(plt.get_cmap("tab10").colors[: max(1, len(cats))])
        ax.imshow(grid, cmap=cmap, vmin=-0.5, vmax=len(cats) - 0.5, aspect="auto",
                  origin="lower", interpolation="nearest")  # fmt: skip
        ax.legend(handles=[Patch(color=cmap(i), label=c) for c, i in idx.items()],
                  loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    else:
        grid = np.array([[np.nan if v is None else float(v) for v in row] for row in hm.values])
        finite = grid[np.isfinite(grid)]
        norm = None
        if how == "median_abs" and finite.size and np.all(finite > 0):
            norm = LogNorm(vmin=float(finite.min()), vmax=max(float(finite.max()),
                                                              float(finite.min()) * 1.0001))
        kw = {"vmin": 0.0, "vmax": 1.0} if how == "fraction" else {}
        im = ax.imshow(grid, cmap="viridis", norm=norm, aspect="auto", origin="lower",
                       interpolation="nearest", **kw)  # fmt: skip
        fig.colorbar(im, ax=ax, label=name)
    if nx * ny <= 400:
        for i in range(ny):
            for j in range(nx):
                v = hm.values[i][j]
                if v is not None:
                    txt = v if isinstance(v, str) else f"{v:.4g}"
                    ax.text(j, i, txt.replace("-pitchfork", "\npitchfork"), ha="center",
                            va="center", fontsize=7, color="k",
                            path_effects=[withStroke(linewidth=2, foreground="w")])
    ax.set_xticks(range(nx), [_label(v) for v in hm.xs], rotation=45 if nx > 6 else 0,
                  fontsize=8)  # fmt: skip
    ax.set_yticks(range(ny), [_label(v) for v in hm.ys], fontsize=8)
    ax.set_xlabel(hm.x)
    ax.set_ylabel(hm.y)
    ax.set_title(title or f"{name} over {hm.x} x {hm.y}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_heatmaps(result: Any, x: str, y: str, out: str | Path,
                   metrics: Sequence[str] | None = None) -> list[Path]:  # fmt: skip
    """PNG + CSV per metric of the atlas's kind (``heatmap-<metric>.png/.csv`` in ``out``).

    Metrics with no value in any cell (e.g. the error of a sweep atlas without
    ``mu_star_true``) are skipped.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    for metric in metrics or KINDS[result.kind].metrics:
        hm = heatmap(result.rows, x, y, metric)
        if all(v is None for row in hm.values for v in row):
            continue
        files.append(write_csv(hm, out / f"heatmap-{metric}.csv"))
        files.append(render_png(hm, out / f"heatmap-{metric}.png",
                                title=f"{result.name}: {METRICS[metric][0]}"))  # fmt: skip
    return files


__all__ = ["METRICS", "Heatmap", "heatmap", "render_png", "write_csv", "write_heatmaps"]
