"""The HTML pages in a real headless Chromium: each page loads with no console error and no
failed request, a screenshot is taken, and the numbers on the page equal the API's.

The server is a real uvicorn on loopback with keys required and two owners (see conftest):
pages act as the API's caller (a key in an HTTP-only cookie set by /login) and another owner's
resource answers 404, as on /v1.
"""

from __future__ import annotations

import json
import math
import time
from typing import Any

import pytest
from _pages_cdp import Browser, Tab
from _pages_site import Site, wait_job

COOKIE = "snapwarn_session"


def _session(site: Site, key: str) -> str:
    """A page session made by logging in with ``key`` (the cookie holds a random token)."""
    import httpx2

    r = httpx2.post(site.base + "/login", data={"key": key, "next": "/"}, timeout=60)
    assert r.status_code == 303, r.text[:300]
    return r.cookies[COOKIE]


def _login_cookie(site: Site, key: str) -> list[dict[str, Any]]:
    return [{"name": COOKIE, "value": _session(site, key), "url": site.base, "httpOnly": True}]


def _open(
    browser: Browser, site: Site, path: str, key: str | None, init_script: str | None = None
) -> Tab:
    browser.call("Storage.clearCookies", {})
    return browser.open(site.base + path, cookies=_login_cookie(site, key) if key else None,
                        init_script=init_script)  # fmt: skip


def _values(tab: Tab) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {}
    for d in tab.data_keys():
        out.setdefault(d["key"], []).append(d)
    return out


def _shown(text: str) -> float:
    """The number a page shows (first token; units follow)."""
    return float(text.replace("%", "").split()[0])


def _close_to_shown(api: float, text: str, digits: int) -> bool:
    """The page's rounded number equals the API's value to the digits shown."""
    return math.isclose(_shown(text), api, rel_tol=10.0 ** (1 - digits), abs_tol=1e-300)


def _assert_clean(tab: Tab) -> None:
    assert tab.errors() == [], f"{tab.url}: {tab.errors()}"


def test_index_lists_the_callers_resources(browser: Browser, site: Site, shots) -> None:
    tab = _open(browser, site, "/", site.key_a)
    _assert_clean(tab)
    tab.screenshot(shots / "index.png")
    links = tab.evaluate("Array.from(document.querySelectorAll('main a')).map(a => a.pathname)")
    assert f"/sweeps/{site.sweep_id}" in links
    assert f"/jobs/{site.sweep_id}" in links
    assert {f"/signals/{i}" for i in site.signals} <= set(links)
    tab.close()
    # another owner sees none of it
    tab = _open(browser, site, "/", site.key_b)
    _assert_clean(tab)
    links = tab.evaluate("Array.from(document.querySelectorAll('main a')).map(a => a.pathname)")
    assert not any(site.sweep_id in x or any(i in x for i in site.signals) for x in links)
    tab.close()


def test_sweep_page_shows_the_apis_warning(browser: Browser, site: Site, shots) -> None:
    with site.client(site.key_a) as c:
        api = c.get(f"/v1/sweeps/{site.sweep_id}").json()
    p, alarm = api["prediction"], api["alarm"]
    tab = _open(browser, site, f"/sweeps/{site.sweep_id}", site.key_a)
    _assert_clean(tab)
    tab.screenshot(shots / "sweep.png")
    v = _values(tab)
    one = {k: xs[0] for k, xs in v.items()}
    # the exact values the API answers, and the numbers the page shows rounded to the
    # interval: its half-width with two significant digits, mu* to the same decimal place
    lo, hi = p["mu_star_interval"]
    places = 1 - math.floor(math.log10(0.5 * (hi - lo)))
    assert one["mu_star"]["value"] == p["mu_star"]
    assert one["mu_star"]["text"] == f"{round(p['mu_star'], places):.{max(places, 0)}f}"
    assert one["mu_star_lo"]["value"] == lo and one["mu_star_hi"]["value"] == hi
    shown_lo, shown_hi = float(one["mu_star_lo"]["text"]), float(one["mu_star_hi"]["text"])
    assert shown_lo <= lo and shown_hi >= hi  # rounded outward, never narrower
    assert hi - shown_hi > -10.0 ** -places and shown_lo - lo > -10.0 ** -places
    assert len(one["mu_star_hi"]["text"].split(".")[-1]) == max(places, 0)
    assert float(one["next_safe_mu"]["text"]) <= p["next_safe_mu"]  # rounded down: still safe
    assert one["alarm_rank"]["value"] == alarm["rank"]
    assert one["a"]["value"] == p["a"]
    assert one["transition"]["value"] == p["transition"] == one["transition"]["text"]
    assert one["alarm_level"]["value"] == alarm["level"] == one["alarm_level"]["text"]
    assert one["t_ratio"]["value"] == alarm["t_ratio"]
    assert one["baseline_mu_star"]["value"] == p["baseline"]["mu_star"]
    assert one["next_safe_mu"]["value"] == p["next_safe_mu"]
    probs = {d["name"]: d["value"] for d in v["probability"]}
    assert probs == p["probabilities"]
    # the sweep found the synthetic strip's transition
    assert p["transition"] == "saddle-node"
    assert p["mu_star_interval"][0] <= 30.0 <= p["mu_star_interval"][1]
    # one row per record, in the API's order, with its control value and period
    dets = api["result"]["detections"]
    assert [d["value"] for d in v["control"]] == [d["control"] for d in dets]
    periods = [2 * math.pi / math.sqrt(-d["fundamental"]["sigma2"]) for d in dets]
    for shown, want in zip(v["period"], periods, strict=True):
        assert math.isclose(shown["value"], want, rel_tol=1e-12)
        assert _close_to_shown(want, shown["text"].split(" (")[0], 4)
        assert shown["text"].endswith(" Hz)")  # the frequency in Hz beside the period in ms
    # every thumbnail (fit over the record) loaded; the chart carries the user's names and units
    n_img = tab.evaluate(
        "Array.from(document.querySelectorAll('img.thumb')).filter(i => i.naturalWidth > 0).length"
    )
    assert n_img == len(dets)
    svg_text = tab.evaluate("document.querySelector('#sweep-chart svg').textContent")
    for label in ("theta [deg]", "period T = 2 pi / omega [ms]", "(T / T0)^(-1/a)",
                  "95 % interval of theta*", "paper's rule", "distance theta* - theta [deg]",
                  "theta - theta* [deg]"):  # fmt: skip
        assert label in svg_text, label
    tab.close()


def test_signal_page_shows_the_apis_detection(browser: Browser, site: Site, shots) -> None:
    sid = site.signals[-1]
    with site.client(site.key_a) as c:
        det = c.post("/v1/detections", json={"signal_id": sid}).json()
        meta = c.get(f"/v1/signals/{sid}").json()
    tab = _open(browser, site, f"/signals/{sid}", site.key_a)
    _assert_clean(tab)
    tab.screenshot(shots / "signal.png")
    v = _values(tab)
    assert [x["value"] for x in v["sigma2"]] == [m["sigma2"] for m in det["modes"]]
    assert [x["value"] for x in v["omega"]] == [m["omega"] for m in det["modes"]]
    assert [x["value"] for x in v["damping"]] == [m["damping"] for m in det["modes"]]
    assert v["static_level"][0]["value"] == det["static_level"]
    assert v["n"][0]["value"] == meta["n"]
    assert v["dt"][0]["value"] == meta["dt"]
    svg_text = tab.evaluate("document.querySelector('#fit-chart svg').textContent")
    for label in ("t [ms]", "w [mm]", "residual [mm]", "detector's fit"):
        assert label in svg_text, label
    tab.close()


def test_job_page_refreshes_while_the_job_runs(browser: Browser, site: Site, shots) -> None:
    with site.client(site.key_a) as c:
        ids = []
        for name in ("second pass", "third pass"):  # one job runner: the third waits its turn
            r = c.post("/v1/sweeps", json={
                "name": name, "measurements": [{"signal_id": i} for i in site.signals],
            })  # fmt: skip
            assert r.status_code == 202, r.text
            ids.append(r.json()["id"])
        job_id = ids[-1]
        tab = _open(browser, site, f"/jobs/{job_id}", site.key_a)
        # the page may be reloading itself when we first look: wait for its status element
        first = tab.wait_for(
            "(document.querySelector('[data-key=status]') || {textContent: ''}).textContent.trim()"
        )
        assert first in ("queued", "running"), first
        assert tab.wait_for("!!document.getElementById('job-script')")
        # the page's script polls and reloads the finished page by itself
        tab.wait_for(
            "document.querySelector('[data-key=status]').textContent.trim() === 'succeeded'",
            timeout=180,
        )
        job = wait_job(c, job_id)
    browser.pump(0.5)
    _assert_clean(tab)
    v = _values(tab)
    assert v["fraction"][0]["value"] == job["progress"]["fraction"] == 1.0
    assert v["message"][0]["text"] == job["progress"]["message"]
    tab.screenshot(shots / "job.png")
    links = tab.evaluate("Array.from(document.querySelectorAll('main a')).map(a => a.pathname)")
    assert f"/sweeps/{job_id}" in links
    tab.close()


def test_pages_respect_keys_and_owners(browser: Browser, site: Site, shots) -> None:
    path = f"/sweeps/{site.sweep_id}"
    # no key: the login form (401), nothing of the sweep
    tab = _open(browser, site, path, None)
    assert tab.evaluate("!!document.querySelector('form.login')")
    assert not tab.evaluate("!!document.querySelector('[data-key=mu_star]')")
    tab.screenshot(shots / "login.png")
    # a wrong key is refused; owner A's key opens the page it was asked for
    tab.evaluate(
        "document.querySelector('input[name=key]').value = 'swk_wrong_key';"
        "document.querySelector('form.login').requestSubmit(); true"
    )
    tab.wait_for("!!document.querySelector('[data-key=login-failed]')")
    tab.evaluate(
        f"document.querySelector('input[name=key]').value = {site.key_a!r};"
        "document.querySelector('form.login').requestSubmit(); true"
    )
    tab.wait_for("!!document.querySelector('[data-key=mu_star]')")
    assert tab.evaluate("location.pathname") == path
    tab.close()
    # owner B: 404, as on /v1
    tab = _open(browser, site, path, site.key_b)
    assert tab.evaluate("document.querySelector('h1').textContent") == "404"
    assert not tab.evaluate("!!document.querySelector('[data-key=mu_star]')")
    tab.close()
    with site.client(site.key_b) as c:
        assert c.get(f"/v1/sweeps/{site.sweep_id}").status_code == 404
        assert c.get(f"/sweeps/{site.sweep_id}/records/0.svg").status_code in (401, 404)


def test_api_docs_render_offline(browser: Browser, site: Site, shots) -> None:
    tab = _open(browser, site, "/docs", None)
    n = tab.wait_for("document.querySelectorAll('.opblock').length", timeout=60)
    assert n >= 10
    _assert_clean(tab)
    urls = [
        e["params"]["request"]["url"]
        for e in browser.events
        if e.get("sessionId") == tab.session and e["method"] == "Network.requestWillBeSent"
    ]
    assert urls and all(u.startswith(site.base) or u.startswith("data:") for u in urls), urls
    tab.screenshot(shots / "docs.png")
    tab.close()


@pytest.mark.parametrize("path", ["/static/swagger-ui/swagger-ui-bundle.js", "/static/style.css"])
def test_static_assets_come_from_the_package(site: Site, path: str) -> None:
    import httpx2

    r = httpx2.get(site.base + path, timeout=30)
    assert r.status_code == 200 and len(r.content) > 1000


def test_time_bound(site: Site) -> None:
    """The sweep page answers within a few seconds (charts drawn server-side)."""
    import httpx2

    cookies = {COOKIE: _session(site, site.key_a)}
    t0 = time.monotonic()
    r = httpx2.get(site.base + f"/sweeps/{site.sweep_id}", cookies=cookies, timeout=60)
    assert r.status_code == 200
    assert time.monotonic() - t0 < 30


def test_api_chart_routes_carry_the_users_units(site: Site) -> None:
    """``/v1/sweeps/{id}/plot.svg|png``: the same chart as the page, the user's names."""
    with site.client(site.key_a) as c:
        svg = c.get(f"/v1/sweeps/{site.sweep_id}/plot.svg")
        png = c.get(f"/v1/sweeps/{site.sweep_id}/plot.png")
    assert svg.status_code == 200 and svg.headers["content-type"].startswith("image/svg+xml")
    for label in ("theta [deg]", "period T = 2 pi / omega [ms]", "95 % interval of theta*"):
        assert label in svg.text, label
    assert png.status_code == 200 and png.content[:8] == b"\x89PNG\r\n\x1a\n"


def _tab_events(browser: Browser, tab: Tab, since: int, method: str) -> list[dict[str, Any]]:
    return [e["params"] for e in browser.events[since:]
            if e.get("sessionId") == tab.session and e["method"] == method]  # fmt: skip


def _requested(browser: Browser, tab: Tab, since: int = 0) -> list[str]:
    return [p["request"]["url"]
            for p in _tab_events(browser, tab, since, "Network.requestWillBeSent")]  # fmt: skip


def _add_record(c: Any, sid: str, rec: tuple) -> None:
    theta, dt, w = rec
    r = c.post(f"/v1/sweeps/{sid}/records",
               json={"w": w.tolist(), "dt": dt, "control": theta, "unit": "s"})  # fmt: skip
    assert r.status_code == 201, r.text


@pytest.mark.slow
def test_live_sweep_page_follows_the_records(browser: Browser, site: Site, shots) -> None:
    """An open live sweep: the page shows the latest update's warning (the API's numbers) and
    follows the sweep's event stream: a record added after the page loaded is pushed to it and
    shown in place, without a reload and without a single polling request. A browser without
    EventSource falls back to polling the job's status."""
    from _pages_site import lab_records

    recs = lab_records()
    with site.client(site.key_a) as c:
        r = c.post("/v1/sweeps", json={"name": "live theta", "mode": "live",
                                       "control": {"name": "theta", "unit": "deg"}})  # fmt: skip
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
        for rec in recs[:6]:
            _add_record(c, sid, rec)
        last = c.get(f"/v1/sweeps/{sid}/records").json()["items"][-1]
        start = len(browser.events)
        tab = _open(browser, site, f"/sweeps/{sid}", site.key_a)
        _assert_clean(tab)
        one = {k: xs[0] for k, xs in _values(tab).items()}
        assert one["mu_star"]["value"] == last["prediction"]["mu_star"]
        assert one["mu_star_lo"]["value"] == last["prediction"]["mu_star_interval"][0]
        assert one["transition"]["value"] == last["prediction"]["transition"]
        assert one["alarm_level"]["value"] == last["alarm"]["level"]
        assert one["next_safe_mu"]["value"] == last["next_control"]
        assert len(_values(tab)["control"]) == 6
        # the records' time unit on the live page too, and each flag once
        head = tab.evaluate("document.querySelector('#records thead').textContent")
        assert "period T [s]" in head, head
        codes = tab.evaluate("Array.from(document.querySelectorAll('#sweep-flags li'))"
                             ".map(e => e.textContent)")  # fmt: skip
        assert len(codes) == len(set(codes)), codes
        # the page follows the stream of the records after the six it shows
        tab.wait_for("document.getElementById('live-script').dataset.following === 'events'")
        streams = [u for u in _requested(browser, tab, start) if "/events" in u]
        assert streams == [f"{site.base}/sweeps/{sid}/events?after=6"], streams
        tab.evaluate("window.__same_document = true")
        mark = len(browser.events)
        _add_record(c, sid, recs[6])
        answered = time.monotonic()
        tab.wait_for("document.querySelectorAll('tr.record').length === 7", timeout=60)
        shown = time.monotonic()
        browser.pump(0.5)
        last = c.get(f"/v1/sweeps/{sid}/records").json()["items"][-1]
    one = {k: xs[0] for k, xs in _values(tab).items()}
    assert one["mu_star"]["value"] == last["prediction"]["mu_star"]
    assert one["next_safe_mu"]["value"] == last["next_control"]
    _assert_clean(tab)
    # pushed: the stream carried record 7, the page was fetched again only after it arrived,
    # in place (the same document), and nothing polled
    pushed = [p for p in _tab_events(browser, tab, mark, "Network.eventSourceMessageReceived")
              if p["eventName"] == "update"]  # fmt: skip
    assert [p["eventId"] for p in pushed] == ["7"]
    assert json.loads(pushed[0]["data"])["seq"] == 7
    fetched = [p for p in _tab_events(browser, tab, mark, "Network.requestWillBeSent")
               if p["request"]["url"] == f"{site.base}/sweeps/{sid}"]  # fmt: skip
    assert fetched and all(p["timestamp"] >= pushed[0]["timestamp"] for p in fetched)
    assert tab.evaluate("window.__same_document === true")
    urls = _requested(browser, tab, start)
    assert not any("status.json" in u for u in urls), urls
    assert len([u for u in urls if "/events" in u]) == 1  # one stream, never reopened
    print(f"record 7 shown {shown - answered:.2f} s after its POST was answered")
    tab.screenshot(shots / "live.png")
    # the fallback: a browser without EventSource polls the job's status and reloads
    start = len(browser.events)
    old = _open(browser, site, f"/sweeps/{sid}", site.key_a,
                init_script="delete window.EventSource;")  # fmt: skip
    assert len(_values(old)["control"]) == 7
    assert old.evaluate("document.getElementById('live-script').dataset.following") is None
    with site.client(site.key_a) as c:
        _add_record(c, sid, recs[7])
    for t in (tab, old):
        t.wait_for("document.querySelectorAll('tr.record').length === 8", timeout=60)
    urls = _requested(browser, old, start)
    assert any("status.json" in u for u in urls) and not any("/events" in u for u in urls)
    assert not any("status.json" in u for u in _requested(browser, tab))
    browser.pump(0.5)
    for t in (tab, old):
        _assert_clean(t)
        t.close()


def test_user_text_is_escaped_in_pages_and_charts(browser: Browser, site: Site) -> None:
    """A record's name and units are the user's text: shown, never run (page and inline SVG)."""
    import numpy as np

    evil = '<img src=x onerror="window.__xss=1">'
    t = np.arange(800) * 0.01
    with site.client(site.key_a) as c:
        w = (np.cos(5 * t) * np.exp(-0.1 * t)).tolist()
        r = c.post("/v1/signals", json={"dt": 0.01, "w": w, "name": evil, "unit": evil,
                                        "value_unit": "mm"})  # fmt: skip
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
    tab = _open(browser, site, f"/signals/{sid}", site.key_a)
    _assert_clean(tab)
    assert tab.evaluate("window.__xss === undefined")
    assert evil in tab.evaluate("document.querySelector('[data-key=name]').textContent")
    assert evil in tab.evaluate("document.querySelector('#fit-chart svg').textContent")
    tab.close()


def test_sweep_pages_show_the_options_used(browser: Browser, site: Site, shots) -> None:
    """The user's hand shown on the pages (issue 27 item 6): a batch sweep's band, notch and
    per-record options (a record excluded by the user is listed as set aside by its name), and
    a live sweep's band, notch, plan and each record's options, given in the multipart form."""
    from _pages_site import lab_records

    recs = lab_records()
    band = [0.01, 1.0]  # rad/ms: around every record's fundamental (0.03-0.31 rad/ms)
    with site.client(site.key_a) as c:
        ms = [{"signal_id": i} for i in site.signals]
        ms[2]["quantity"] = "displacement"
        ms[3]["exclude"] = True
        r = c.post("/v1/sweeps", json={"name": "with options", "measurements": ms,
                                       "band": band})  # fmt: skip
        assert r.status_code == 202, r.text
        batch = r.json()["id"]
        wait_job(c, batch)
        api = c.get(f"/v1/sweeps/{batch}").json()["result"]
        excluded = c.get(f"/v1/signals/{site.signals[3]}").json()["name"]
        r = c.post("/v1/sweeps", json={"name": "live with options", "mode": "live",
                                       "control": {"name": "theta", "unit": "deg"},
                                       "band": band, "notch": [0.3],
                                       "live": {"step": 5.0, "margin": 0.01}})  # fmt: skip
        assert r.status_code == 201, r.text
        live = r.json()["id"]
        for k, (theta, dt, w) in enumerate(recs[:5]):
            rows = (f"{j * dt!r},{float(x)!r}\n" for j, x in enumerate(w))
            body = "t [ms],w [mm]\n" + "".join(rows)
            form = {"control": repr(theta), "quantity": "displacement"}
            if k == 1:
                form["notch"] = "0.25, 0.35"
            r = c.post(f"/v1/sweeps/{live}/records", data=form,
                       files={"file": (f"rec_{k}.csv", body.encode())})  # fmt: skip
            assert r.status_code == 201, r.text
            assert r.json()["record_name"] == f"rec_{k}.csv"
        ups = c.get(f"/v1/sweeps/{live}/records").json()["items"]
    # the batch sweep: the options, each record's name and what it was read with
    assert [a["name"] for a in api["set_aside"]] == [excluded]
    assert excluded in " ".join(f["message"] for f in api["flags"])
    tab = _open(browser, site, f"/sweeps/{batch}", site.key_a)
    _assert_clean(tab)
    v = _values(tab)
    opt = {d["name"]: d["value"] for d in v["option"]}
    assert opt["band"] == "[0.01, 1] rad per time unit"
    assert opt["notch"].startswith("none given")
    assert [d["value"] for d in v["record_name"]] == [d["record_name"] for d in api["detections"]]
    names = {d["name"]: d["record_name"] for d in api["detections"]}  # signal id -> its name
    assert names[site.signals[3]] == excluded
    shown = {d["value"] for d in v["record_options"]}
    assert "displacement; excluded by the user" in shown and "displacement" in shown
    tab.close()
    # the live sweep: its plan, band and notch, each record's name and options
    tab = _open(browser, site, f"/sweeps/{live}", site.key_a)
    _assert_clean(tab)
    tab.screenshot(shots / "live-options.png")
    v = _values(tab)
    opt = {d["name"]: d["value"] for d in v["option"]}
    assert opt["band"] == "[0.01, 1] rad per time unit"
    assert opt["notch"] == "0.3 cycles per time unit"
    assert opt["step"] == "5" and opt["margin"] == "0.01"
    assert opt["target_width"].startswith("1e-6") and opt["method"] == "auto"
    assert [d["value"] for d in v["record_name"]] == [f"rec_{k}.csv" for k in range(5)]
    ro = [d["value"] for d in v["record_options"]]
    assert ro[1] == "displacement; notch 0.25, 0.35" and ro[0] == "displacement; notch 0.3"
    assert [u["record_options"]["notch"] for u in ups] == [[0.3], [0.25, 0.35], [0.3], [0.3],
                                                           [0.3]]  # fmt: skip
    tab.close()
