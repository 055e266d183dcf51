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

from service.client._core import JSON_HEADERS, Call, Flow, dumps, wait_flow
from service.client._ops import Operations, operation
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


class AtlasOperations(Operations):
    """``/v1/atlases``, declared once for both clients (see :mod:`service.client._ops`)."""

    @operation
    def create_atlas(self, spec: Any, *, name: str | None = None) -> Flow[Atlas]:
        """``POST /v1/atlases``: a spec (dict, model, or .json/.yaml path) -> the atlas (202)."""
        return (yield create_atlas(spec, name=name))

    @operation
    def get_atlas(self, atlas_id: str) -> Flow[Atlas]:
        """``GET /v1/atlases/{id}``: progress (cells done) and, once done, the summary."""
        return (yield get_atlas(atlas_id))

    @operation
    def list_atlases(self, *, limit: int = 50, offset: int = 0) -> Flow[AtlasPage]:
        """``GET /v1/atlases``: a page of atlases, newest first."""
        return (yield list_atlases(limit=limit, offset=offset))

    @operation
    def atlas_cells(self, atlas_id: str, **kw: Any) -> Flow[AtlasCellPage]:
        """``GET /v1/atlases/{id}/cells``: finished cells (``limit``, ``offset``, ``status``)."""
        return (yield atlas_cells(atlas_id, **kw))

    @operation
    def atlas_heatmap(self, atlas_id: str, **kw: Any) -> Flow[bytes]:
        """PNG or CSV heatmap of a result (``metric``, ``x``, ``y``, ``format``)."""
        return (yield atlas_heatmap(atlas_id, **kw))

    @operation
    def wait_atlas(self, atlas: Any, **kw: Any) -> Flow[Atlas]:
        """Wait for the atlas's job (see :meth:`Client.wait`), then the refreshed atlas."""
        job = atlas.job.id if isinstance(atlas, Atlas) else atlas
        opts = {"progress": False, "timeout": None, "poll": 0.25, "raise_on_failure": True, **kw}
        yield from wait_flow(job, **opts)
        return (yield get_atlas(_id(atlas)))
