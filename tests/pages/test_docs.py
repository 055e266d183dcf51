"""The README and docs/ stand alone: every relative link resolves inside the repository and no
path points outside it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)\s]+)\)")


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_links_resolve_inside_the_repository(doc: Path) -> None:
    text = doc.read_text()
    for target in LINK.findall(text):
        if target.startswith(("http://", "https://", "mailto:")):
            continue
        path = target.split("#", 1)[0]
        if not path:
            continue
        resolved = (doc.parent / path).resolve()
        assert resolved.is_relative_to(ROOT), f"{doc.name}: {target} leaves the repository"
        assert resolved.exists(), f"{doc.name}: {target} does not exist"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_path_outside_the_repository(doc: Path) -> None:
    text = doc.read_text()
    for bad in ("../", "/work/", "/tmp/", "shared/paper", "DESIGN.md"):
        assert bad not in text, f"{doc.name} mentions {bad!r}"


def test_readme_starts_with_the_two_commands() -> None:
    lines = [ln.strip() for ln in (ROOT / "README.md").read_text().splitlines() if ln.strip()]
    assert lines[1].startswith("make demo") and lines[2].startswith("make test")
    text = (ROOT / "README.md").read_text()
    assert ".venv/bin/snapwarn" in text and ". .venv/bin/activate" in text


def test_license_is_the_declared_one() -> None:
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")
    assert 'license = "MIT"' in (ROOT / "pyproject.toml").read_text()


def test_package_data_ships_every_page_asset() -> None:
    """An installed wheel serves the pages: pyproject's package-data covers every template and
    static file (Swagger UI included)."""
    import fnmatch
    import tomllib

    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())
    globs = conf["tool"]["setuptools"]["package-data"]["service.api.pages"]
    pages = ROOT / "service" / "api" / "pages"
    files = [p for d in ("templates", "static") for p in (pages / d).rglob("*") if p.is_file()]
    assert any(p.name == "swagger-ui-bundle.js" for p in files)
    for p in files:
        rel = p.relative_to(pages).as_posix()
        assert any(fnmatch.fnmatchcase(rel, g) and rel.count("/") == g.count("/")
                   for g in globs), rel  # fmt: skip
