"""Atlas methods of the SDK (mixed into :class:`Client` and :class:`AsyncClient`).

>>> with Client("http://127.0.0.1:8000") as c:                       # doctest: +SKIP
...     atlas = c.create_atlas({"kind": "bifurcation", "fixed": {"model": "cosserat"},
...                             "grid": {"slenderness": [1e-3, 5e-3],
...                                      "actuation": ["asymmetric", "symmetric"]}})
...     atlas = c.wait_atlas(atlas)
...     rows = c.atlas_cells(atlas.id).items
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from service.client._core import JSON_HEADERS, Call, dumps
from service.schemas.atlases import Atlas, AtlasCellPage, AtlasPage


def _model(cls: Any) -> Any:
    return lambda r: cls.model_validate(r.json())


def spec_document(spec: Any) -> dict[str, Any]:
    """A spec as a mapping: a dict, a pydantic model, or a path to a .json/.yaml file."""
    if isinstance(spec, Mapping):
        return dict(spec)
    if hasattr(spec, "model_dump"):
        return spec.model_dump(mode="json", exclude_none=True, by_alias=True)
    p = Path(spec)
    text = p.read_text()
    if p.suffix.lower() == ".json":
        return json.loads(text)
    import yaml

    return yaml.safe_load(text)


def create_atlas(spec: Any, *, name: str | None = None) -> Call:
    doc: dict[str, Any] = {"spec": spec_document(spec)}
    if name is not None:
        doc["name"] = name
    return Call("POST", "/v1/atlases", content=dumps(doc), headers=dict(JSON_HEADERS),
                parse=_model(Atlas))  # fmt: skip


def get_atlas(atlas_id: str) -> Call:
    return Call("GET", f"/v1/atlases/{atlas_id}", parse=_model(Atlas))


def list_atlases(*, limit: int = 50, offset: int = 0) -> Call:
    return Call("GET", "/v1/atlases", params={"limit": limit, "offset": offset},
                parse=_model(AtlasPage))  # fmt: skip


def atlas_cells(atlas_id: str, *, limit: int = 500, offset: int = 0,
                status: str | None = None) -> Call:  # fmt: skip
    params: dict[str, Any] = {"limit": limit, "offset": offset}
    if status is not None:
        params["status"] = status
    return Call("GET", f"/v1/atlases/{atlas_id}/cells", params=params,
                parse=_model(AtlasCellPage))  # fmt: skip


def atlas_heatmap(atlas_id: str, *, metric: str = "mu_star", x: str | None = None,
                  y: str | None = None, format: str = "png") -> Call:  # fmt: skip
    if format not in ("png", "csv"):
        raise ValueError(f"format must be 'png' or 'csv', got {format!r}")
    params = {k: v for k, v in (("metric", metric), ("x", x), ("y", y)) if v is not None}
    return Call("GET", f"/v1/atlases/{atlas_id}/heatmap.{format}", params=params,
                parse=lambda r: r.content)  # fmt: skip


def _id(atlas: Any) -> str:
    return atlas if isinstance(atlas, str) else atlas.id


class AtlasMethods:
    """``/v1/atlases`` for the blocking client."""

    def create_atlas(self, spec: Any, *, name: str | None = None) -> Atlas:
        """``POST /v1/atlases``: a spec (dict, model, or .json/.yaml path) -> the atlas (202)."""
        return self._run(create_atlas(spec, name=name))  # type: ignore[attr-defined]

    def get_atlas(self, atlas_id: str) -> Atlas:
        """``GET /v1/atlases/{id}``: progress (cells done) and, once done, the summary."""
        return self._run(get_atlas(atlas_id))  # type: ignore[attr-defined]

    def list_atlases(self, *, limit: int = 50, offset: int = 0) -> AtlasPage:
        """``GET /v1/atlases``: a page of atlases, newest first."""
        return self._run(list_atlases(limit=limit, offset=offset))  # type: ignore[attr-defined]

    def atlas_cells(self, atlas_id: str, **kw: Any) -> AtlasCellPage:
        """``GET /v1/atlases/{id}/cells``: finished cells (``limit``, ``offset``, ``status``)."""
        return self._run(atlas_cells(atlas_id, **kw))  # type: ignore[attr-defined]

    def atlas_heatmap(self, atlas_id: str, **kw: Any) -> bytes:
        """PNG or CSV heatmap of a result (``metric``, ``x``, ``y``, ``format``)."""
        return self._run(atlas_heatmap(atlas_id, **kw))  # type: ignore[attr-defined]

    def wait_atlas(self, atlas: Any, **kw: Any) -> Atlas:
        """Wait for the atlas's job (see :meth:`Client.wait`), then the refreshed atlas."""
        self.wait(atlas.job.id if isinstance(atlas, Atlas) else atlas, **kw)  # type: ignore[attr-defined]
        return self.get_atlas(_id(atlas))


class AsyncAtlasMethods:
    """``/v1/atlases`` for the asyncio client (the same methods, awaitable)."""

    async def create_atlas(self, spec: Any, *, name: str | None = None) -> Atlas:
        return await self._run(create_atlas(spec, name=name))  # type: ignore[attr-defined]

    async def get_atlas(self, atlas_id: str) -> Atlas:
        return await self._run(get_atlas(atlas_id))  # type: ignore[attr-defined]

    async def list_atlases(self, *, limit: int = 50, offset: int = 0) -> AtlasPage:
        return await self._run(list_atlases(limit=limit, offset=offset))  # type: ignore[attr-defined]

    async def atlas_cells(self, atlas_id: str, **kw: Any) -> AtlasCellPage:
        return await self._run(atlas_cells(atlas_id, **kw))  # type: ignore[attr-defined]

    async def atlas_heatmap(self, atlas_id: str, **kw: Any) -> bytes:
        return await self._run(atlas_heatmap(atlas_id, **kw))  # type: ignore[attr-defined]

    async def wait_atlas(self, atlas: Any, **kw: Any) -> Atlas:
        await self.wait(atlas.job.id if isinstance(atlas, Atlas) else atlas, **kw)  # type: ignore[attr-defined]
        return await self.get_atlas(_id(atlas))
