"""The predictor package's shape: no import circle among its modules (nor with the analysis
modules around it), and its map (the ``__init__`` docstring) names every module."""

from __future__ import annotations

import ast
from pathlib import Path

import service.analysis.predictor as predictor_pkg

ANALYSIS = Path(predictor_pkg.__file__).resolve().parents[1]
ROOT = ANALYSIS.parents[1]


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _graph() -> dict[str, set[str]]:
    """Module -> the analysis modules it imports (at any depth of its body)."""
    mods = {_module_name(p): p for p in ANALYSIS.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module:
                targets = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            deps |= {t for t in targets if t in mods and t != name}
        graph[name] = deps
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle of ``graph`` (a package importing its own submodules through its
    ``__init__`` excepted: Python resolves those), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        stack.append(m)
        for d in sorted(graph[m]):
            if m.startswith(d + "."):  # a submodule's parent package: imported first anyway
                continue
            if state.get(d) == 1:
                return stack[stack.index(d):] + [d]
            if d not in state and (c := visit(d)):
                return c
        stack.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (c := visit(m)):
            return c
    return None


def test_the_cycle_finder_finds_a_circle() -> None:
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_no_import_circle_in_the_analysis_package() -> None:
    graph = _graph()
    assert "service.analysis.predictor.prediction" in graph
    assert _cycle(graph) is None, _cycle(graph)


def test_the_map_names_every_module_of_the_predictor() -> None:
    doc = predictor_pkg.__doc__ or ""
    pkg = Path(predictor_pkg.__file__).parent
    for p in pkg.rglob("*.py"):
        if p.name == "__init__.py":
            continue
        rel = p.relative_to(pkg).with_suffix("").as_posix()
        assert rel.replace("/", ".") in doc or rel in doc, f"{rel} missing from the map"
