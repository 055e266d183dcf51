"""OpenAPI links beyond "an id and the operations on it": what a client (and a stateful fuzzer,
schemathesis) can do next with what an answer gave it.

``service.api.app`` links every creating POST to the operations on the resource it created
(``$response.body#/id``). These add the chains whose request needs a *body* the answer makes
possible: a stored signal detected and swept, a live sweep fed a record and that record read
back, a simulation followed by an atlas of its model's bifurcations, a prediction refitted
with one law. A link's ``requestBody`` is sent as given (``x-schemathesis.merge_body``:
false): runtime expressions (``$response.body#/id``) filled in, the rest literal, so each
chain reaches the work behind the door (a detection, a sweep job, a live record, an atlas job,
a prediction) instead of stopping at a 422 on a random body.
"""

from __future__ import annotations

import math
from typing import Any

#: A clean ring-down (0.8 cycles per time unit, decaying, 256 samples): a record every
#: detector reads.
_DT = 0.05
_W = [round(math.exp(-0.15 * k * _DT) * math.cos(2 * math.pi * 0.8 * k * _DT), 6)
      for k in range(256)]  # fmt: skip
#: A saddle-node table: sigma2 = -4 sqrt(1 - mu), mu* = 1.
_MU = [0.5, 0.6, 0.7, 0.75, 0.8, 0.85, 0.9]
_S2 = [round(-4.0 * math.sqrt(1.0 - m), 6) for m in _MU]

EXAMPLE_PREDICTION = {"mu": _MU, "sigma2": _S2}
EXAMPLE_RECORD = {"control": 0.1, "dt": _DT, "w": _W}
EXAMPLE_ATLAS = {
    "spec": {"kind": "bifurcation", "fixed": {"model": "normal-form"},
             "grid": {"actuation": ["asymmetric", "symmetric", "antisymmetric"]}},
}  # fmt: skip
EXAMPLE_SIGNAL = {"dt": _DT, "w": _W, "name": "ring-down", "control": {"name": "mu", "value": 0.1}}

#: Request examples (JSON) by creating door: documentation, and what a fuzzer's example phase
#: sends (schemathesis also mixes them into the bodies it generates, so that the stateful
#: phase's chains start from a created resource).
EXAMPLES: dict[str, dict[str, Any]] = {
    "/v1/signals": {"ring-down": EXAMPLE_SIGNAL},
    "/v1/detections": {"inline": {"dt": _DT, "w": _W}},
    "/v1/predictions": {"saddle-node": EXAMPLE_PREDICTION},
    "/v1/simulations": {"normal-form": {"model": "normal-form", "mu": -0.5}},
    "/v1/sweeps": {"live": {"mode": "live", "control": {"name": "mu"}},
                   "simulated": {"simulate": {"model": "normal-form", "seed": 1}}},
    "/v1/sweeps/{sweep_id}/records": {"inline": EXAMPLE_RECORD},
    "/v1/atlases": {"normal-form": EXAMPLE_ATLAS},
}  # fmt: skip

_LITERAL = {"x-schemathesis": {"merge_body": False}}

#: (source path, method, status) -> {link name: (target path, method, parameters, body, what)}
LINKS: dict[tuple[str, str, str], dict[str, tuple[str, str, dict[str, str], Any, str]]] = {
    ("/v1/signals", "post", "201"): {
        "post_detection": ("/v1/detections", "post", {}, {"signal_id": "$response.body#/id"},
                           "Detect the modes of the stored signal."),
        "post_sweep": ("/v1/sweeps", "post", {}, {"measurements": [
            {"signal_id": "$response.body#/id", "control_value": c} for c in (0.1, 0.2, 0.3)]},
            "A batch sweep of the stored signal (at three controls)."),
    },
    ("/v1/sweeps", "post", "201"): {
        "post_record_inline": ("/v1/sweeps/{sweep_id}/records", "post",
                               {"sweep_id": "$response.body#/id"}, EXAMPLE_RECORD,
                               "Add an inline record to the live sweep."),
    },
    ("/v1/sweeps/{sweep_id}/records", "post", "201"): {
        "get_record": ("/v1/sweeps/{sweep_id}/records/{seq}", "get",
                       {"sweep_id": "$request.path.sweep_id", "seq": "$response.body#/seq"},
                       None, "The warning after this record."),
        "post_close": ("/v1/sweeps/{sweep_id}/close", "post",
                       {"sweep_id": "$request.path.sweep_id"}, None, "Close the live sweep."),
    },
    **{("/v1/simulations", "post", code): {
        "post_atlas": ("/v1/atlases", "post", {}, EXAMPLE_ATLAS,
                       "An atlas of the normal form's bifurcations over the actuations."),
    } for code in ("201", "202")},
    ("/v1/predictions", "post", "200"): {
        "post_refit": ("/v1/predictions", "post", {},
                       {"mu": "$request.body#/mu", "sigma2": "$request.body#/sigma2",
                        "transition": "saddle-node"},
                       "The same table fitted with the saddle-node law only."),
    },
}  # fmt: skip


def _pointer(path: str, method: str) -> str:
    return "#/paths/" + path.replace("~", "~0").replace("/", "~1") + "/" + method


def add_links(doc: dict[str, Any]) -> None:
    """Add :data:`LINKS` and :data:`EXAMPLES` to ``doc`` (an OpenAPI document)."""
    paths = doc.get("paths", {})
    for (path, method, status), links in LINKS.items():
        response = paths.get(path, {}).get(method, {}).get("responses", {}).get(status)
        if response is None:
            continue
        out = response.setdefault("links", {})
        for name, (target, tmethod, params, body, what) in links.items():
            if tmethod not in paths.get(target, {}):
                continue
            link: dict[str, Any] = {"operationRef": _pointer(target, tmethod), "description": what}
            if params:
                link["parameters"] = params
            if body is not None:
                link["requestBody"] = body
                link.update(_LITERAL)
            out[name] = link
    for path, examples in EXAMPLES.items():
        media = paths.get(path, {}).get("post", {}).get("requestBody", {}).get("content", {})
        if "application/json" in media:
            media["application/json"].setdefault(
                "examples", {k: {"value": v} for k, v in examples.items()}
            )
