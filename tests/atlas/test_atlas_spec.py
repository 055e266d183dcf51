"""The atlas spec: expansion, stable keys, and errors that name the field and the value."""

from __future__ import annotations

import json
import math

import pytest

from service.atlas import SpecError, cell_key, load_spec, parse_spec


def _spec(**kw: object) -> dict:
    doc = {"kind": "bifurcation", "fixed": {"model": "cosserat", "elements": 20},
           "grid": {"slenderness": [1e-3, 2e-3], "actuation": ["asymmetric", "symmetric"]}}
    doc.update(kw)
    return doc


def test_grid_is_the_product_in_row_major_order_with_defaults_filled() -> None:
    s = parse_spec(_spec())
    assert [c.index for c in s.cells] == [0, 1, 2, 3]
    assert [(c.inputs["slenderness"], c.inputs["actuation"]) for c in s.cells] == [
        (1e-3, "asymmetric"), (1e-3, "symmetric"), (2e-3, "asymmetric"), (2e-3, "symmetric")]
    c = s.cells[0].inputs
    assert c["end_shortening"] == 1e-2 and c["poisson"] == 0.5
    assert c["elements"] == 20 and c["rtol"] == 2e-4
    assert s.varied == ("slenderness", "actuation") and s.chart == ("slenderness", "actuation")


def test_ranges_linear_and_log() -> None:
    s = parse_spec(_spec(grid={"slenderness": {"from": 1e-3, "to": 1e-2, "num": 4},
                               "actuation": ["asymmetric"]}))
    assert [c.inputs["slenderness"] for c in s.cells] == pytest.approx([1e-3, 4e-3, 7e-3, 1e-2])
    s = parse_spec(_spec(grid={"slenderness": {"from": 1e-4, "to": 1e-2, "num": 3,
                                               "scale": "log"}, "actuation": ["symmetric"]}))
    assert [c.inputs["slenderness"] for c in s.cells] == pytest.approx([1e-4, 1e-3, 1e-2])


def test_keys_are_stable_and_depend_on_every_input() -> None:
    a = parse_spec(_spec()).cells[0]
    # the same cell written as a list, keys in another order, defaults spelt out
    b = parse_spec({"kind": "bifurcation", "cells": [
        {"poisson": 0.5, "rtol": 2e-4, "actuation": "asymmetric", "slenderness": 1e-3,
         "elements": 20, "model": "cosserat", "end_shortening": 0.01}]}).cells[0]
    assert a.key == b.key and len(a.key) == 24
    assert cell_key("bifurcation", a.inputs) == a.key
    for name, other in (("elements", 22), ("slenderness", 1.0000001e-3), ("poisson", 0.3)):
        assert cell_key("bifurcation", {**a.inputs, name: other}) != a.key
    assert cell_key("warn", a.inputs) != a.key


@pytest.mark.parametrize(
    ("doc", "field", "value"),
    [
        ({"kind": "bifurcatio", "grid": {}}, "kind", "bifurcatio"),
        (_spec(grid={"slenderness": [1e-3, -1.0], "actuation": ["symmetric"]}),
         "grid.slenderness[1]", -1.0),
        (_spec(grid={"thickness": [1e-3]}), "grid.thickness", "thickness"),
        (_spec(grid={"actuation": ["asymmetric", "sideways"]}), "grid.actuation[1]", "sideways"),
        (_spec(grid={"actuation": ["symmetric", "symmetric"]}), "grid.actuation[1]",
         "symmetric"),
        (_spec(fixed={"model": "cosserat", "elements": 21}, grid={"actuation": ["symmetric"]}),
         "grid.elements", 21),
        (_spec(grid={"slenderness": [1e-3]}), "grid.actuation", None),
        (_spec(cells=[{"actuation": "symmetric"}]), "grid", None),
        (_spec(grid={"slenderness": {"from": 1e-3, "to": 1e-2}, "actuation": ["symmetric"]}),
         "grid.slenderness", {"from": 1e-3, "to": 1e-2}),
        (_spec(grid={"slenderness": [math.nan], "actuation": ["symmetric"]}),
         "grid.slenderness[0]", None),
        (_spec(chart={"x": "slenderness", "y": "damping"}), "chart.y", "damping"),
        (_spec(retries=-1), "retries", -1),
        (_spec(colour="red"), "colour", "red"),
        ({"kind": "warn", "cells": [{"actuation": "symmetric", "damping": "lots"}]},
         "cells[0].damping", "lots"),
        ({"kind": "warn", "cells": [{"actuation": "symmetric"}, {"actuation": "symmetric",
                                                                "seed": 0}]}, "cells[1]", None),
    ],
)
def test_errors_name_the_field_and_value(doc: dict, field: str, value: object) -> None:
    with pytest.raises(SpecError) as info:
        parse_spec(doc)
    err = info.value
    assert err.parameter == field, str(err)
    assert field.split("[")[0].split(".")[-1] in str(err) or field in str(err)
    if value is not None:
        assert err.value == value
        assert repr(value) in str(err) or str(value) in str(err)


def test_load_spec_reads_yaml_and_json_and_resolves_manifests(tmp_path) -> None:  # noqa: ANN001
    (tmp_path / "a.yaml").write_text("kind: sweep\ncells:\n  - {manifest: data/m1.csv}\n")
    s = load_spec(tmp_path / "a.yaml")
    assert s.cells[0].inputs["manifest"] == str((tmp_path / "data/m1.csv").resolve())
    (tmp_path / "b.json").write_text(json.dumps(_spec()))
    assert len(load_spec(tmp_path / "b.json").cells) == 4
    (tmp_path / "c.json").write_text("{kind: ")
    with pytest.raises(SpecError, match="not valid JSON") as info:
        load_spec(tmp_path / "c.json")
    assert info.value.parameter == "SPEC"


def test_the_example_specs_are_valid() -> None:
    from pathlib import Path

    examples = sorted((Path(__file__).resolve().parents[2] / "examples").glob("atlas-*.yaml"))
    assert len(examples) >= 3
    for path in examples:
        spec = load_spec(path)
        assert spec.cells and spec.chart is not None, path
