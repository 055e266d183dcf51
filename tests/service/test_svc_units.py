"""Units at the API's doors, against a real uvicorn: signals whose control values or time units
cannot go in one sweep are refused at the door (422 naming the field), never mixed; a unit a
file states is not overridden by a form field."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from service.client import Client, InvalidInput

MU = [0.0, 0.5, 1.0, 1.3, 1.5]


def _csv(d: Path, name: str, mu: float, unit: str | None) -> Path:
    """A ring-down at ``mu`` (sigma^2 = -400 sqrt(1.8 - mu)), time column in ``unit``."""
    t = 2e-3 * np.arange(3000)
    om = math.sqrt(400 * math.sqrt(1.8 - mu))
    w = 0.05 + 1e-2 * np.exp(-0.02 * t) * np.sin(om * t)
    scale, head = {"ms": (1e3, "t [ms]"), "s": (1.0, "t [s]"), None: (1.0, "t")}[unit]
    p = d / name
    p.write_text(f"{head},w\n" + "".join(f"{a * scale:.9g},{b:.9g}\n" for a, b in zip(t, w)))
    return p


@pytest.fixture(scope="module")
def client(live_server):  # noqa: ANN001, ANN201
    with Client(live_server.url, timeout=120.0) as c:
        yield c


def test_control_values_in_different_units_are_refused(client: Client, tmp_path: Path) -> None:
    """Signals stored with control units rad and deg alternately: the sweep ran with controls
    [0, 0.17, 0.26, 5, 13...] and answered mu* = 29.4."""
    ids = []
    for k, mu in enumerate(MU):
        deg = k % 2 == 1
        sig = client.upload_file(
            _csv(tmp_path, f"r{k}.csv", mu, "s"), control_name="theta",
            control_value=10 * mu if deg else math.radians(10 * mu),
            control_unit="deg" if deg else "rad",
        )  # fmt: skip
        ids.append(sig.id)
    with pytest.raises(InvalidInput) as err:
        client.create_sweep(ids, name="mixed controls")
    assert err.value.field == "measurements" and "different units" in str(err.value)


def test_a_missing_time_unit_among_others_is_refused_at_the_door(
    client: Client, tmp_path: Path
) -> None:
    """Files in ms and one without a unit: the job was accepted (202) and failed later."""
    ids = [client.upload_file(_csv(tmp_path, f"m{k}.csv", mu, "ms" if k else None),
                              control_value=mu).id for k, mu in enumerate(MU)]  # fmt: skip
    with pytest.raises(InvalidInput) as err:
        client.create_sweep(ids, name="mixed times")
    assert err.value.field == "measurements" and "none given" in str(err.value)
    # known units only (ms and s): accepted, analysed in seconds
    ids = [client.upload_file(_csv(tmp_path, f"k{k}.csv", mu, "ms" if k % 2 else "s"),
                              control_value=mu).id for k, mu in enumerate(MU)]  # fmt: skip
    sweep = client.wait(client.create_sweep(ids, name="ms and s"), timeout=300)
    s2 = [m.sigma2 for m in sweep.result.measurements]
    assert s2 == pytest.approx([-400 * math.sqrt(1.8 - mu) for mu in MU], rel=1e-3)


def test_a_form_unit_does_not_override_the_files(client: Client, tmp_path: Path) -> None:
    p = _csv(tmp_path, "ms.csv", 0.0, "ms")
    with pytest.raises(InvalidInput) as err:
        client.upload_file(p, unit="s")
    assert err.value.field == "unit"
    assert client.upload_file(p, unit="ms").unit == "ms"  # the same unit: fine


def test_a_live_sweep_refuses_a_signals_control_in_another_unit(
    client: Client, tmp_path: Path
) -> None:
    live = client.live_sweep("deg sweep", control="theta", unit="deg", step=5.0)
    sig = client.upload_file(_csv(tmp_path, "rad.csv", 0.0, "s"), control_name="theta",
                             control_value=0.0, control_unit="rad")  # fmt: skip
    with pytest.raises(InvalidInput) as err:
        live.add(signal_id=sig.id, control=None)
    assert err.value.field == "control"
    u = live.add(signal_id=sig.id, control=0.0)  # its value given in the sweep's unit: fine
    assert u.control == 0.0
    live.close()
