"""The seam's layering: the reader and the converter know no HTTP; the numerics know no web."""

from __future__ import annotations

import subprocess
import sys

import pytest


def _loaded_after(imports: str) -> set[str]:
    code = f"import sys\n{imports}\nprint('\\n'.join(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return set(out.stdout.split())


@pytest.mark.parametrize(
    "imports, forbidden",
    [
        ("import service.recordings", ("fastapi", "starlette", "service.api", "pydantic")),
        ("import service.convert", ("fastapi", "starlette", "service.api", "sqlalchemy")),
        ("import sim, service.analysis.detect, service.analysis.pipeline",
         ("fastapi", "starlette", "pydantic", "sqlalchemy", "service.api")),  # fmt: skip
    ],
)
def test_layers(imports: str, forbidden: tuple[str, ...]) -> None:
    loaded = _loaded_after(imports)
    bad = sorted(m for m in loaded if m.split(".")[0] in forbidden or m.startswith(forbidden))
    assert bad == [], f"{imports!r} loads {bad[:5]}"
