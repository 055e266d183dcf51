"""A file that cannot be read, through every door: set aside by its name with the reader's
reason, and the sweep goes on (issue 29: "an unreadable file: the batch sweep sets it aside,
the live door answers 4xx, ``watch`` skips it").

References: the batch door (``snapwarn sweep`` on a manifest) is the definition. The live
sweep in process, ``snapwarn watch`` (in process and through a server) and the live door over
HTTP with the SDK give its answer, alarm, advice and set-aside list (name and reason). The live
door still answers the upload with the reader's problem (422 naming the field: the lab hears
at once that its file is broken) and keeps the record set aside in the sweep (its detail says
which record). The batch API sweeps stored signals: such a file is refused at its upload
(``/v1/signals``) and never becomes a signal, so a batch of signals cannot hold it; the batch
of the others gives the same answer, alarm and advice (docs/lab-guide.md, "Records set
aside").
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from _records import DT, MU_STAR, record

from service import convert
from service.analysis import live

ROOT = Path(__file__).resolve().parents[2]
CONTROLS = [0.0, 0.3, 0.6, 0.9, 1.2, 1.5]
BROKEN = 2  # rec_02: a cell that is no number
REASON = "its file cannot be read (file: line 4, column 'w': 'x' is not a number)"


def _wire(doc: dict) -> tuple:
    """The answer, alarm, advice and records set aside of a wire document."""
    p = doc.get("prediction") or doc
    alarm = doc["alarm"][-1] if isinstance(doc["alarm"], list) else doc["alarm"]
    aside = [(a["name"], a["reason"]) for a in doc["set_aside"]]
    return (p.get("transition"), p.get("mu_star"), p.get("mu_star_interval"), alarm,
            doc["next_control"], aside)  # fmt: skip


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> SimpleNamespace:
    """Six closed-form records as CSV files (``rec_<k>_mu_<control>.csv``), the third with a
    cell that is no number; the manifest; the live sweep in process fed them one by one."""
    folder = tmp_path_factory.mktemp("unreadable")
    names = []
    for k, mu in enumerate(CONTROLS):
        t, w = record(mu, n=2000)
        name = f"rec_{k:02d}_mu_{mu!r}.csv"
        rows = [f"{float(a)!r},{float(b)!r}" for a, b in zip(t, w, strict=True)]
        if k == BROKEN:
            rows[2] = f"{float(t[2])!r},x"
        (folder / name).write_text("t [s],w\n" + "\n".join(rows) + "\n")
        names.append(name)
    manifest = folder / "manifest.csv"
    manifest.write_text("path,control\n" + "".join(f"{n},{c!r}\n"
                                                  for n, c in zip(names, CONTROLS)))  # fmt: skip
    recs, docs = [], []
    for k, (name, mu) in enumerate(zip(names, CONTROLS, strict=True)):
        if k == BROKEN:
            u = live.update_unreadable(recs, mu, REASON, name=name,
                                       time_unit=live.sweep_time_unit(recs))  # fmt: skip
        else:
            u = live.update(recs, record(mu, n=2000)[1], dt=DT, control=mu, name=name,
                            time_unit="s")  # fmt: skip
        recs.append(u.record)
        docs.append(convert.live_update(u).model_dump(mode="json"))
    return SimpleNamespace(folder=folder, names=names, manifest=manifest, docs=docs)


def _cli(*args: str) -> tuple[int, dict]:
    from service.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main([*args, "--json"])
    return rc, json.loads(out.getvalue())


def _watch(folder: Path, *extra: str) -> list[dict]:
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-c", "import sys; from service.cli import main; sys.exit(main())",
           "watch", str(folder), "--control", r"_mu_(?P<control>[-+0-9.eE]+)\.csv$", "--json",
           "--budget", str(len(CONTROLS)), "--idle", "60", *extra]  # fmt: skip
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    return [json.loads(x) for x in r.stdout.splitlines() if x.strip().startswith("{")]


def test_the_batch_and_the_live_sweep_set_it_aside_by_name(files: SimpleNamespace) -> None:
    """``snapwarn sweep`` (before: the reason held the manifest entry's full path) and the live
    sweep in process: the file set aside by its name with the reader's reason, the others
    answer, the same answer, alarm and advice."""
    rc, doc = _cli("sweep", str(files.manifest), "--no-progress")
    assert rc == 0
    assert doc["set_aside"] == [{"seq": BROKEN + 1, "control": CONTROLS[BROKEN],
                                 "name": files.names[BROKEN],
                                 "reason": f"record {files.names[BROKEN]} set aside: {REASON}"}]
    assert _wire(doc) == _wire(files.docs[-1])
    # the batch document advises the next record as the live door does
    keys = ("record_duration", "record_dt", "record_advice")
    assert [doc[k] for k in keys] == [files.docs[-1][k] for k in keys]
    assert doc["record_duration"] > 0 and "40 periods" in doc["record_advice"]
    lo, hi = doc["prediction"]["mu_star_interval"]
    assert lo <= MU_STAR <= hi
    bad = files.docs[BROKEN]  # the update of the unreadable record itself
    assert not bad["used_in_fit"] and bad["record_name"] == files.names[BROKEN]
    assert bad["detection"]["modes"] == [] and bad["detection"]["n_samples"] == 0
    assert [f["code"] for f in bad["record_flags"]] == ["record_set_aside"]


def test_watch_sets_it_aside_and_goes_on(files: SimpleNamespace) -> None:
    """``snapwarn watch`` in process (before: 'skipped', no update): one update per file, the
    broken one set aside, each as the live sweep in process gives it."""
    docs = _watch(files.folder)
    assert len(docs) == len(CONTROLS)
    for k, (d, ref) in enumerate(zip(docs, files.docs, strict=True)):
        assert _wire(d) == _wire(ref), k
        assert d["record_name"] == ref["record_name"] and d["used_in_fit"] == ref["used_in_fit"]


@pytest.mark.slow
def test_http_sdk_and_remote_watch_keep_it_set_aside(files: SimpleNamespace, server) -> None:  # noqa: ANN001
    """The live door over HTTP with the SDK: the upload of the broken file is answered 422
    naming the field, its detail says which record keeps it; that record (and every later
    update) lists it set aside by name with the reason, as in process; ``snapwarn watch
    --server`` prints that record's update. The batch API of the stored signals: the broken
    file is refused at its upload; the others give the CLI's answer, alarm and advice."""
    from service.client import Client
    from service.client.errors import InvalidInput

    with Client(server.url, timeout=600.0) as sdk:
        sweep = sdk.live_sweep("unreadable")
        got = []
        for k, (name, mu) in enumerate(zip(files.names, CONTROLS, strict=True)):
            if k == BROKEN:
                with pytest.raises(InvalidInput) as err:
                    sweep.add(files.folder / name, control=mu)
                p = err.value.problem
                assert p.errors[0].field == "file: line 4, column 'w'"
                assert f"set aside, as record {k + 1}" in p.detail
                got.append(sweep.records(after=k).items[0].model_dump(mode="json"))
            else:
                got.append(sweep.add(files.folder / name, control=mu).model_dump(mode="json"))
        for k, (d, ref) in enumerate(zip(got, files.docs, strict=True)):
            assert _wire(d) == _wire(ref), k
        closed = sweep.close()
        assert [a.name for a in closed.result.set_aside] == [files.names[BROKEN]]
        # the batch API: the broken file is never a signal
        ids = []
        for k, (name, mu) in enumerate(zip(files.names, CONTROLS, strict=True)):
            if k == BROKEN:
                with pytest.raises(InvalidInput):
                    sdk.upload_file(files.folder / name, control_value=mu)
                continue
            ids.append((sdk.upload_file(files.folder / name, control_value=mu).id, mu))
        batch = sdk.wait(sdk.create_sweep(ids), timeout=600.0)
        doc = batch.result.model_dump(mode="json")
        assert doc["set_aside"] == []
        assert _wire(doc)[:5] == _wire(files.docs[-1])[:5]
    remote = _watch(files.folder, "--server", server.url)
    assert len(remote) == len(CONTROLS)
    for k, (d, ref) in enumerate(zip(remote, files.docs, strict=True)):
        assert _wire(d) == _wire(ref), k


def test_a_first_file_that_cannot_be_read_leaves_the_time_unit_to_the_next() -> None:
    """The sweep's time unit is its first record's that was read: a first file that cannot
    be read has none, and the next (in seconds) is not refused for a unit it lacks."""
    u0 = live.update_unreadable([], 0.0, REASON, name="a.csv")
    assert u0.record.time_unit is None and live.sweep_time_unit([u0.record], "s") == "s"
    u1 = live.update([u0.record], record(0.3, n=2000)[1], dt=DT, control=0.3, time_unit="s")
    assert live.sweep_time_unit([u0.record, u1.record]) == "s"
    assert np.isfinite(u1.detection.fundamental.sigma2)
