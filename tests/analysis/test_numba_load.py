"""Cached kernels loaded without refreshing numba's whole target context
(``service.analysis._numba_load``) run as they do with numba's own loader: same results, the
runtime (arrays returned) available, and a later cache miss still compiles. Each case runs fresh
interpreters (a process loads a kernel once)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numba
import pytest

from service.analysis._numba_load import CHECKED

pytestmark = pytest.mark.skipif(
    not numba.__version__.startswith(CHECKED),
    reason=f"numba {numba.__version__}: the fast loader applies to {CHECKED} only (numba's own "
    "loader runs, unchanged)",
)

_KERNELS = """
import numpy as np
from numba import njit

@njit(cache=True)
def ramp(n):
    return np.arange(n) * 0.5

@njit(cache=True)
def total(x):
    return x.sum()
"""

_RUN = """
import json, sys
sys.path.insert(0, sys.argv[1])
from service.analysis._numba_load import install
applied = install() if sys.argv[2] == "patched" else False
import kern
a = kern.ramp(5)                    # cached: loaded, returns an array (numba's runtime)
s = kern.total(a.astype("float32")) # float32: not in the cache, compiled after the load
print(json.dumps({"applied": applied, "a": a.tolist(), "s": float(s),
                  "hits": sum(kern.ramp.stats.cache_hits.values()),
                  "misses": sum(kern.total.stats.cache_misses.values())}))
"""


def _run(code: str, *argv: str, env: dict[str, str] | None = None) -> dict:
    r = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                       timeout=600, env={**os.environ, **(env or {})})  # fmt: skip
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_a_cached_kernel_loads_and_a_miss_still_compiles(tmp_path: Path) -> None:
    (tmp_path / "kern.py").write_text(_KERNELS)
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    first = _run(_RUN, str(tmp_path), "plain", env=env)  # compiles and caches ramp and total
    assert first["hits"] == 0
    for f in (tmp_path / "cache").rglob("*total*"):
        f.unlink()  # total is a miss again
    second = _run(_RUN, str(tmp_path), "patched", env=env)
    assert second["applied"] is True
    assert second["hits"] == 1 and second["misses"] == 1
    assert second["a"] == first["a"] == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert second["s"] == first["s"] == 5.0


_DETECT = """
import json, sys
import numpy as np
from service.analysis.detect import detect
from service.analysis import _numba_load
t = np.arange(4000) * 1e-3
rng = np.random.default_rng(3)
w = np.r_[np.zeros(400), np.exp(-2 * t[:3600]) * np.sin(40 * t[:3600])
          + 0.3 * np.exp(-5 * t[:3600]) * np.sin(130 * t[:3600])] + 1e-3 * rng.normal(size=4000)
d = detect(w, dt=1e-3)
from service.analysis.detect import _kernels
hits = sum(sum(getattr(_kernels, k).stats.cache_hits.values()) for k in ("model_gram", "psd_pinv"))
print(json.dumps({"patched": _numba_load._installed, "hits": hits, "modes": [
    [m.omega, m.sigma2, m.sigma2_std, m.amplitude] for m in d.modes],
    "flags": [f.code for f in d.flags]}))
"""


def test_detect_is_the_same_with_numbas_full_refresh() -> None:
    full = _run(_DETECT, env={"SNAPWARN_NUMBA_FULL_REFRESH": "1"})  # fills a cold cache
    fast = _run(_DETECT)
    assert fast.pop("patched") is True and full.pop("patched") is False
    assert fast.pop("hits") >= 2  # read from the cache by the fast loader
    full.pop("hits")
    assert fast == full  # bit for bit (json floats round-trip)


_IMPORT = """
import json, sys
from service.analysis import _numba_load
numba = _numba_load.import_numba()
before = {m: m in sys.modules for m in ("scipy", "yaml")}
import scipy, yaml  # import normally afterwards
from numba.core import config
print(json.dumps({"before": before, "same": numba is _numba_load.import_numba(),
                  "njit": _numba_load.njit is numba.njit, "scipy": scipy.__version__,
                  "perf_warnings_off": config.DISABLE_PERFORMANCE_WARNINGS}))
"""


def test_numba_imports_without_scipy_and_yaml_which_import_normally_after(
    tmp_path: Path,
) -> None:
    out = subprocess.run([sys.executable, "-c", _IMPORT], capture_output=True, text=True,
                         timeout=600, cwd=tmp_path)  # fmt: skip
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["before"] == {"scipy": False, "yaml": False}
    assert r["same"] and r["njit"] and r["scipy"]
    assert r["perf_warnings_off"] == 0


def test_numbas_config_file_is_still_read(tmp_path: Path) -> None:
    """With ``.numba_config.yaml`` in the working directory yaml is imported, and the file
    applies (here: a setting whose default is 0)."""
    (tmp_path / ".numba_config.yaml").write_text("disable_performance_warnings: 1\n")
    out = subprocess.run([sys.executable, "-c", _IMPORT], capture_output=True, text=True,
                         timeout=600, cwd=tmp_path)  # fmt: skip
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["before"] == {"scipy": False, "yaml": True}
    assert r["perf_warnings_off"] == 1


_NEEDS = """
import json, sys
from service.analysis._numba_load import import_numba
assert "numpy" not in sys.modules and "numba" not in sys.modules
numba = import_numba(without=("numpy",))  # numba cannot import without numpy: the plain way
import numpy
from numba import njit
f = njit(lambda x: x + 1)
print(json.dumps({"numba": numba is sys.modules["numba"], "f": f(numpy.float64(1.5))}))
"""


def test_a_numba_that_needs_a_kept_out_module_is_imported_the_plain_way() -> None:
    out = subprocess.run([sys.executable, "-c", _NEEDS], capture_output=True, text=True,
                         timeout=600)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {"numba": True, "f": 2.5}


_THREADED = """
import json, sys, threading, time
from service.analysis import _numba_load
stop = threading.Event()
t = threading.Thread(target=stop.wait, daemon=True)
t.start()
_numba_load.import_numba()
print(json.dumps({m: m in sys.modules for m in ("scipy", "yaml")}))
stop.set()
"""


def test_nothing_is_kept_out_while_other_threads_run(tmp_path: Path) -> None:
    """Another thread could import scipy while it is marked absent: then numba imports plainly."""
    out = subprocess.run([sys.executable, "-c", _THREADED], capture_output=True, text=True,
                         timeout=600, cwd=tmp_path)  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {"scipy": True, "yaml": True}


_LOCK = """
import json, sys, threading
sys.path.insert(0, sys.argv[1])
from service.analysis._numba_load import install
install()
from llvmlite.binding import ffi
from numba.core import event
before = list(ffi.lib._lock._cblist)
n = [0]
class Count(event.Listener):
    def on_start(self, ev): n[0] += 1
    def on_end(self, ev): pass
if sys.argv[2] == "threaded":
    stop = threading.Event()
    threading.Thread(target=stop.wait).start()
import kern
with event.install_listener("numba:llvm_lock", Count()):
    a = kern.ramp(5)  # cached: loaded
if sys.argv[2] == "threaded":
    stop.set()
print(json.dumps({"events": n[0], "restored": ffi.lib._lock._cblist == before,
                  "callbacks": len(before), "hits": sum(kern.ramp.stats.cache_hits.values()),
                  "a": a.tolist()}))
"""


def test_a_cached_load_broadcasts_no_llvm_lock_events_and_restores_the_callbacks(
    tmp_path: Path,
) -> None:
    (tmp_path / "kern.py").write_text(_KERNELS)
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    _run(_RUN, str(tmp_path), "plain", env=env)  # fills the cache
    alone = _run(_LOCK, str(tmp_path), "alone", env=env)
    assert alone["hits"] == 1 and alone["a"] == [0.0, 0.5, 1.0, 1.5, 2.0]
    assert alone["callbacks"] >= 1 and alone["restored"] is True
    assert alone["events"] == 0
    # another thread alive: the callbacks (global) are left alone, the events broadcast
    threaded = _run(_LOCK, str(tmp_path), "threaded", env=env)
    assert threaded["hits"] == 1 and threaded["restored"] is True
    assert threaded["events"] > 0
