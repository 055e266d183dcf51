"""The atlas SPEC: a small JSON/YAML document naming the cells to compute.

A spec has one ``kind`` (``bifurcation``, ``warn`` or ``sweep``, see :mod:`service.atlas.cells`)
and either a ``grid`` (the product of its axes, in the order written) or an explicit list of
``cells``; ``fixed`` holds the parameters common to all cells::

    kind: bifurcation
    name: table-1
    fixed: {model: cosserat, end_shortening: 1.0e-2, elements: 200}
    grid:
      slenderness: {from: 1.0e-3, to: 1.0e-2, num: 10}    # linspace (scale: log for logspace)
      actuation: [asymmetric, symmetric, antisymmetric]
    chart: {x: slenderness, y: actuation}                 # heatmap axes (optional)

Every error is a :class:`SpecError` naming the field (``grid.slenderness[3]``) and its value.
Each cell is keyed by a stable hash of its kind and its complete inputs (defaults filled in),
so the same cell has the same key in every run, on every machine: a restarted atlas skips the
keys already persisted, and the scheduler never runs one key twice at the same time.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from service.analysis.errors import ParameterError
from service.atlas.cells import KINDS, ParamSpec

MAX_CELLS = 100_000
SPEC_KEYS = ("kind", "name", "fixed", "grid", "cells", "chart", "retries", "timeout_s")
KEY_VERSION = 1  # bump when a kind's results change meaning: old persisted cells are then redone


class SpecError(ParameterError):
    """An atlas spec is invalid: ``.parameter`` is the field's path, ``.value`` its value."""


@dataclass(frozen=True)
class Cell:
    """One independent computation of an atlas.

    Attributes
    ----------
    index : int
        Position in the spec's order (row-major over the grid's axes).
    key : str
        Stable hash (sha256, 24 hex digits) of the kind and the complete inputs.
    inputs : dict
        Every parameter of the kind, defaults filled in (JSON values).
    """

    index: int
    key: str
    inputs: dict[str, Any]


@dataclass(frozen=True)
class AtlasSpec:
    """A validated atlas spec.

    Attributes
    ----------
    kind : {"bifurcation", "warn", "sweep"}
    name : str
    fixed : dict
        Parameters common to all cells (validated).
    axes : tuple of (name, tuple of values)
        The grid's axes in order (empty for an explicit list of cells).
    cells : tuple of Cell
    chart : tuple of (str, str) or None
        The heatmap's x and y parameters.
    retries : int
        Extra attempts of a cell whose task raised (dask ``retries``); a cell lost with its
        worker is rescheduled by the scheduler in any case.
    timeout_s : float
        Bound on the whole atlas's wall time (cells not done by then are reported, not lost:
        a rerun computes them).
    """

    kind: str
    name: str
    fixed: dict[str, Any]
    axes: tuple[tuple[str, tuple[Any, ...]], ...]
    cells: tuple[Cell, ...]
    chart: tuple[str, str] | None = None
    retries: int = 2
    timeout_s: float = 86_400.0
    source: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def varied(self) -> tuple[str, ...]:
        """Parameters that change from cell to cell (the grid's axes, or the list's keys)."""
        if self.axes:
            return tuple(name for name, _ in self.axes)
        names: list[str] = []
        for c in self.cells:
            for k, v in c.inputs.items():
                if k not in names and any(o.inputs.get(k) != v for o in self.cells):
                    names.append(k)
        return tuple(names)

    def to_dict(self) -> dict[str, Any]:
        """The spec as given (normalised): kind, name, fixed, grid or cells, chart, limits."""
        doc: dict[str, Any] = {"kind": self.kind, "name": self.name, "fixed": dict(self.fixed)}
        if self.axes:
            doc["grid"] = {name: list(vals) for name, vals in self.axes}
        else:
            doc["cells"] = [
                {k: v for k, v in c.inputs.items() if self.fixed.get(k, _MISSING) != v}
                for c in self.cells
            ]
        if self.chart:
            doc["chart"] = {"x": self.chart[0], "y": self.chart[1]}
        doc["retries"] = self.retries
        doc["timeout_s"] = self.timeout_s
        return doc


_MISSING = object()


def cell_key(kind: str, inputs: Mapping[str, Any]) -> str:
    """Stable hash of a cell: sha256 of the canonical JSON of (version, kind, inputs)."""
    doc = json.dumps([KEY_VERSION, kind, dict(inputs)], sort_keys=True, separators=(",", ":"),
                     allow_nan=False)  # fmt: skip
    return hashlib.sha256(doc.encode()).hexdigest()[:24]


def load_spec(path: str | Path) -> AtlasSpec:
    """Read and validate a spec file (``.json``, ``.yaml``/``.yml``).

    Relative ``manifest`` paths (sweep atlases) are resolved against the spec's folder.
    """
    p = Path(path)
    if not p.is_file():
        raise SpecError("SPEC", str(path), f"SPEC: {str(path)!r} is not a readable file")
    text = p.read_text()
    try:
        if p.suffix.lower() == ".json":
            doc = json.loads(text)
        else:
            import yaml

            doc = yaml.safe_load(text)
    except Exception as exc:  # noqa: BLE001 - any parser error is the file's fault
        raise SpecError("SPEC", str(path), f"SPEC: {str(path)!r} is not valid "
                        f"{'JSON' if p.suffix.lower() == '.json' else 'YAML'}: {exc}") from None
    return parse_spec(doc, base_dir=p.resolve().parent)


def _axis_values(name: str, raw: Any, where: str) -> list[Any]:
    if isinstance(raw, Mapping):
        unknown = set(raw) - {"from", "to", "num", "scale"}
        if unknown or not {"from", "to", "num"} <= set(raw):
            raise SpecError(where, raw, f"{where}: a range needs 'from', 'to', 'num' (and "
                            f"optionally 'scale': linear|log), got {dict(raw)!r}")
        a, b, n, scale = raw["from"], raw["to"], raw["num"], raw.get("scale", "linear")
        for key, v in (("from", a), ("to", b)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise SpecError(f"{where}.{key}", v, f"{where}.{key}: must be a finite number, "
                                f"got {v!r}")
        if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_CELLS:
            raise SpecError(f"{where}.num", n, f"{where}.num: must be an integer in "
                            f"[1, {MAX_CELLS}], got {n!r}")
        if scale not in ("linear", "log"):
            raise SpecError(f"{where}.scale", scale, f"{where}.scale: must be 'linear' or "
                            f"'log', got {scale!r}")
        if scale == "log" and (a <= 0 or b <= 0):
            raise SpecError(where, raw, f"{where}: a log range needs from > 0 and to > 0, got "
                            f"from={a!r}, to={b!r}")
        if n == 1:
            return [float(a)]
        if scale == "log":
            la, lb = math.log10(a), math.log10(b)
            return [float(10 ** (la + (lb - la) * k / (n - 1))) for k in range(n)]
        return [float(a + (b - a) * k / (n - 1)) for k in range(n)]
    if isinstance(raw, (str, bytes)) or not isinstance(raw, Sequence):
        raise SpecError(where, raw, f"{where}: an axis is a list of values or a range "
                        f"{{from, to, num}}, got {raw!r}")
    if len(raw) == 0:
        raise SpecError(where, [], f"{where}: an axis needs at least one value")
    return list(raw)


def _check_value(pspec: ParamSpec, value: Any, where: str) -> Any:
    try:
        return pspec.check(value)
    except ValueError as exc:
        raise SpecError(where, value, f"{where}: {exc}") from None


def _check_names(kind: str, names: Any, where: str) -> None:
    params = KINDS[kind].params
    for name in names:
        if name not in params:
            raise SpecError(where + f".{name}", name, f"{where}: unknown parameter {name!r} for "
                            f"kind {kind!r}; known: {', '.join(sorted(params))}")


def parse_spec(doc: Any, *, base_dir: Path | None = None) -> AtlasSpec:
    """Validate a spec document (a mapping, e.g. parsed JSON or YAML) and expand its cells.

    Parameters
    ----------
    doc : mapping
        See the module docstring.
    base_dir : Path, optional
        Folder against which relative ``manifest`` paths are resolved (sweep atlases).

    Raises
    ------
    SpecError
        Naming the field (``grid.damping[2]``, ``cells[4].actuation``, ``kind``) and the value.
    """
    if not isinstance(doc, Mapping):
        raise SpecError("spec", doc, f"spec: must be a mapping, got {type(doc).__name__}")
    for k in doc:
        if k not in SPEC_KEYS:
            raise SpecError(str(k), doc[k], f"{k}: unknown field (given {doc[k]!r}); known: "
                           f"{', '.join(SPEC_KEYS)}")
    kind = doc.get("kind")
    if kind not in KINDS:
        raise SpecError("kind", kind, f"kind: must be one of {', '.join(KINDS)}, got {kind!r}")
    params = KINDS[kind].params
    name = doc.get("name") or kind
    if not isinstance(name, str) or len(name) > 200:
        raise SpecError("name", name, f"name: must be a string of at most 200 characters, "
                        f"got {name!r}")
    fixed_raw = doc.get("fixed") or {}
    if not isinstance(fixed_raw, Mapping):
        raise SpecError("fixed", fixed_raw, f"fixed: must be a mapping, got {fixed_raw!r}")
    _check_names(kind, fixed_raw, "fixed")
    fixed = {k: _check_value(params[k], v, f"fixed.{k}") for k, v in fixed_raw.items()}
    grid, cells_raw = doc.get("grid"), doc.get("cells")
    if (grid is None) == (cells_raw is None):
        raise SpecError("grid", grid, "grid: give exactly one of 'grid' (axes) or 'cells' (a "
                        "list)")
    if grid is not None:
        axes, rows = _expand_grid(kind, grid, fixed)
    else:
        axes, rows = [], _list_cells(kind, cells_raw)
    cells: list[Cell] = []
    seen_keys: dict[str, str] = {}
    for index, (vary, where) in enumerate(rows):
        inputs = _complete(kind, {**fixed, **vary}, where, base_dir)
        key = cell_key(kind, inputs)
        if key in seen_keys:
            raise SpecError(where, vary, f"{where}: the same cell as {seen_keys[key]}")
        seen_keys[key] = where
        cells.append(Cell(index=index, key=key, inputs=inputs))
    varied = [a for a, _ in axes] or sorted({k for v, _ in rows for k in v})
    chart = _chart(doc.get("chart"), varied)
    retries = doc.get("retries", 2)
    if isinstance(retries, bool) or not isinstance(retries, int) or not 0 <= retries <= 10:
        raise SpecError("retries", retries, f"retries: must be an integer in [0, 10], got "
                        f"{retries!r}")
    timeout = doc.get("timeout_s", 86_400.0)
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or not (
        math.isfinite(timeout) and 0 < timeout <= 30 * 86_400
    ):
        raise SpecError("timeout_s", timeout, f"timeout_s: must be a number of seconds in "
                        f"(0, {30 * 86_400}], got {timeout!r}")
    return AtlasSpec(kind=kind, name=name, fixed=fixed, axes=tuple(axes), cells=tuple(cells),
                     chart=chart, retries=retries, timeout_s=float(timeout),
                     source=dict(doc))  # fmt: skip


def _expand_grid(kind: str, grid: Any, fixed: dict[str, Any]
                 ) -> tuple[list[tuple[str, tuple[Any, ...]]], list[tuple[dict, str]]]:  # fmt: skip
    """The grid's validated axes and its cells (row-major product) with their origin."""
    params = KINDS[kind].params
    if not isinstance(grid, Mapping) or not grid:
        raise SpecError("grid", grid, f"grid: must be a non-empty mapping of axes, got {grid!r}")
    _check_names(kind, grid, "grid")
    axes: list[tuple[str, tuple[Any, ...]]] = []
    total = 1
    for pname, raw in grid.items():
        if pname in fixed:
            raise SpecError(f"grid.{pname}", raw, f"grid.{pname}: also given in 'fixed'")
        vals = _axis_values(pname, raw, f"grid.{pname}")
        vals = [_check_value(params[pname], v, f"grid.{pname}[{i}]") for i, v in enumerate(vals)]
        seen: dict[str, int] = {}
        for i, v in enumerate(vals):
            j = seen.setdefault(json.dumps(v, sort_keys=True), i)
            if j != i:
                raise SpecError(f"grid.{pname}[{i}]", v, f"grid.{pname}[{i}]: duplicates "
                                f"grid.{pname}[{j}] ({v!r})")
        axes.append((str(pname), tuple(vals)))
        total *= len(vals)
        if total > MAX_CELLS:
            raise SpecError("grid", total, f"grid: {total} cells or more exceed the limit of "
                            f"{MAX_CELLS}")
    names = [a for a, _ in axes]
    rows = [(dict(zip(names, combo)), "grid") for combo in itertools.product(*(v for _, v in axes))]
    return axes, rows


def _list_cells(kind: str, cells_raw: Any) -> list[tuple[dict, str]]:
    """The explicit list's cells, validated, with their origin ``cells[i]``."""
    params = KINDS[kind].params
    if isinstance(cells_raw, (str, bytes, Mapping)) or not isinstance(cells_raw, Sequence):
        raise SpecError("cells", cells_raw, f"cells: must be a list of mappings, got {cells_raw!r}")
    if not 1 <= len(cells_raw) <= MAX_CELLS:
        raise SpecError("cells", len(cells_raw), f"cells: needs 1 to {MAX_CELLS} cells, got "
                        f"{len(cells_raw)}")
    rows = []
    for i, c in enumerate(cells_raw):
        if not isinstance(c, Mapping):
            raise SpecError(f"cells[{i}]", c, f"cells[{i}]: must be a mapping, got {c!r}")
        _check_names(kind, c, f"cells[{i}]")
        rows.append(({k: _check_value(params[k], v, f"cells[{i}].{k}") for k, v in c.items()},
                     f"cells[{i}]"))  # fmt: skip
    return rows


def _complete(kind: str, given: dict[str, Any], where: str, base_dir: Path | None) -> dict:
    """Fill in defaults, check required parameters and the kind's cross-field rules."""
    spec = KINDS[kind]
    inputs: dict[str, Any] = {}
    for pname, p in spec.params.items():
        if pname in given:
            inputs[pname] = given[pname]
        elif p.required:
            raise SpecError(f"{where}.{pname}", None, f"{where}: parameter {pname!r} is "
                            f"required for kind {kind!r} (in 'fixed', the grid or each cell)")
        else:
            inputs[pname] = p.default
    if kind == "sweep" and base_dir is not None:
        m = Path(inputs["manifest"])
        inputs["manifest"] = str(m if m.is_absolute() else (base_dir / m).resolve())
    try:
        spec.cross_check(inputs)
    except ValueError as exc:
        param = getattr(exc, "parameter", where)
        raise SpecError(f"{where}.{param}" if param != where else where,
                        inputs.get(param, None), f"{where}: {exc}") from None  # fmt: skip
    return inputs


def _chart(raw: Any, varied: Sequence[str]) -> tuple[str, str] | None:
    if raw is None:
        return (varied[0], varied[1]) if len(varied) >= 2 else None
    if not isinstance(raw, Mapping) or set(raw) - {"x", "y"} or not {"x", "y"} <= set(raw):
        raise SpecError("chart", raw, f"chart: must be {{x: AXIS, y: AXIS}}, got {raw!r}")
    for k in ("x", "y"):
        if raw[k] not in varied:
            raise SpecError(f"chart.{k}", raw[k], f"chart.{k}: must be one of the varied "
                            f"parameters {list(varied)}, got {raw[k]!r}")
    if raw["x"] == raw["y"]:
        raise SpecError("chart.y", raw["y"], f"chart.y: must differ from chart.x ({raw['x']!r})")
    return (str(raw["x"]), str(raw["y"]))
