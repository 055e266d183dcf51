"""The corpus of hostile and malformed requests the service must answer with a clear 4xx.

Each case is ``(label, method, path, request kwargs, allowed statuses, field)``: the answer must
be one of the statuses (never 5xx) and, where ``field`` is given, name that field. Used by
``test_svc_hardening.py``, one test per case and database (the pass rate is pytest's count of
them: ``pytest tests/service/test_svc_hardening.py -k attack``).
"""

from __future__ import annotations

import functools
import io
import json
import zipfile

import numpy as np
from _svc_bombs import mat_bomb

__all__ = ["CASES", "W", "deep_json", "mat_bomb", "npz_bomb"]


def _wav(channels: int = 2, n: int = 64) -> bytes:
    from scipy.io import wavfile

    out = io.BytesIO()
    wavfile.write(out, 1000, (np.arange(n * channels).reshape(n, channels) % 100).astype("<i2"))
    return out.getvalue()


def _mat_struct() -> bytes:
    from scipy.io import savemat

    out = io.BytesIO()
    savemat(out, {"w": {"a": np.arange(3.0), "b": "text"}, "dt": 0.1})
    return out.getvalue()


@functools.lru_cache(maxsize=4)
def npz_bomb(uncompressed: int = 1 << 30) -> bytes:
    """An NPZ whose one array inflates to ``uncompressed`` bytes (zeros compress ~1000x)."""
    n = uncompressed // 8
    header = b"\x93NUMPY\x01\x00"
    text = f"{{'descr': '<f8', 'fortran_order': False, 'shape': ({n},), }}".encode()
    text += b" " * (64 - (len(header) + 2 + len(text) + 1) % 64) + b"\n"
    head = header + len(text).to_bytes(2, "little") + text
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        with z.open("w.npy", "w", force_zip64=True) as f:
            f.write(head)
            chunk = b"\x00" * (1 << 22)
            left = n * 8
            while left > 0:
                f.write(chunk[: min(left, len(chunk))])
                left -= len(chunk)
    return out.getvalue()


def deep_json(depth: int) -> str:
    return "[" * depth + "]" * depth


W = [0.0, 1.0, 0.5, -0.3, 0.1, 0.0, -0.05, 0.02]

CASES: list[tuple[str, str, str, dict, tuple[int, ...], str | None]] = [
    ("offset beyond int64 (signals)", "GET", "/v1/signals?offset=100000000000000000000", {},
     (422,), "offset"),
    ("offset beyond int64 (jobs)", "GET", "/v1/jobs?offset=9223372036854775808", {}, (422,),
     "offset"),
    ("offset beyond int64 (sweeps)", "GET", "/v1/sweeps?offset=1e30", {}, (422,), "offset"),
    ("huge damping", "POST", "/v1/simulations",
     {"json": {"model": "normal-form", "damping": 1e300}}, (422,), "damping"),
    ("huge kick", "POST", "/v1/simulations",
     {"json": {"model": "normal-form", "kick": 1e300}}, (422,), "kick"),
    ("Cosserat duration 1e5", "POST", "/v1/simulations",
     {"json": {"model": "cosserat", "duration": 1e5}}, (422,), "duration"),
    ("elements 1e7", "POST", "/v1/simulations", {"json": {"elements": 10_000_000}}, (422,),
     "elements"),
    ("dt 1e308 (duration overflows)", "POST", "/v1/signals",
     {"json": {"dt": 1e308, "w": W}}, (422,), "dt"),
    ("dt subnormal", "POST", "/v1/signals", {"json": {"dt": 5e-324, "w": W}}, (422,), "dt"),
    ("t0 + duration overflows", "POST", "/v1/signals",
     {"json": {"dt": 1e300, "t0": 1.7e308, "w": W}}, (422,), None),
    ("NUL in a query string", "GET", "/v1/jobs?kind=%00", {}, (422,), "kind"),
    ("NUL in a path id", "GET", "/v1/signals/ab%00cd", {}, (404, 422), None),
    ("NUL in a name", "POST", "/v1/signals",
     {"json": {"dt": 0.1, "w": W, "name": "a\u0000b"}}, (201, 422), None),
    ("WAV channel=inf", "POST", "/v1/signals",
     {"files": {"file": ("r.wav", _wav(), "audio/wav")}, "data": {"channel": "inf"}}, (422,),
     "channel"),
    ("WAV channel=1e400", "POST", "/v1/signals",
     {"files": {"file": ("r.wav", _wav(), "audio/wav")}, "data": {"channel": "1e400"}}, (422,),
     "channel"),
    (".mat whose w is a struct", "POST", "/v1/signals",
     {"files": {"file": ("r.mat", _mat_struct(), "application/octet-stream")}}, (415, 422), None),
    ("metadata nested 100,000 deep (JSON)", "POST", "/v1/signals",
     {"content": ('{"dt": 0.1, "w": [1, 2, 3, 4], "metadata": {"x": ' + deep_json(100_000)
                  + "}}").encode(), "headers": {"content-type": "application/json"}},
     (413, 422), None),
    ("metadata nested 100,000 deep (form)", "POST", "/v1/signals",
     {"files": {"file": ("r.csv", b"t,w\n0,1\n1,2\n2,3\n", "text/csv")},
      "data": {"metadata": '{"x": ' + deep_json(100_000) + "}"}}, (413, 422), "metadata"),
    ("detection dt subnormal", "POST", "/v1/detections", {"json": {"w": W * 8, "dt": 5e-324}},
     (422,), "dt"),
    ("detection dt 1e300", "POST", "/v1/detections", {"json": {"w": W * 8, "dt": 1e300}},
     (422,), "dt"),
    ("detection dt 1e-300", "POST", "/v1/detections", {"json": {"w": W * 8, "dt": 1e-300}},
     (200, 422), None),
    ("booleans as samples", "POST", "/v1/signals",
     {"json": {"dt": 0.1, "w": [True, False, True, False]}}, (422,), None),
    ("one sample (no duration)", "POST", "/v1/signals", {"json": {"dt": 0.1, "w": [1.0]}},
     (422,), "w"),
    ("one timed sample", "POST", "/v1/signals", {"json": {"t": [0.0], "w": [1.0]}}, (422,),
     None),
    ("dt zero", "POST", "/v1/signals", {"json": {"dt": 0, "w": W}}, (422,), "dt"),
    ("dt negative", "POST", "/v1/signals", {"json": {"dt": -1, "w": W}}, (422,), "dt"),
    ("sweep of 2 signals", "POST", "/v1/sweeps",
     {"json": {"measurements": [{"signal_id": "a", "control_value": 1},
                                {"signal_id": "b", "control_value": 2}]}}, (422,),
     "measurements"),
    ("text/plain POST", "POST", "/v1/signals",
     {"content": json.dumps({"dt": 0.1, "w": W}).encode(),
      "headers": {"content-type": "text/plain"}}, (415,), "content-type"),
    ("url-encoded POST", "POST", "/v1/sweeps",
     {"content": b"a=1", "headers": {"content-type": "application/x-www-form-urlencoded"}},
     (415,), "content-type"),
    ("cross-site multipart POST", "POST", "/v1/signals",
     {"files": {"file": ("r.csv", b"t,w\n0,1\n1,2\n2,3\n", "text/csv")},
      "headers": {"origin": "https://evil.example"}}, (403,), "origin"),
    ("cross-site DELETE", "DELETE", "/v1/signals/x",
     {"headers": {"origin": "https://evil.example"}}, (403,), "origin"),
    ("sandboxed (null) origin POST", "POST", "/v1/sweeps",
     {"json": {}, "headers": {"origin": "null"}}, (403,), "origin"),
    ("DNS rebinding Host from a browser", "GET", "/v1/signals",
     {"headers": {"host": "evil.example:8000", "sec-fetch-site": "same-origin"}}, (403,),
     "host"),
    ("cancel a job that does not exist", "POST", "/v1/jobs/nope/cancel", {}, (404,), None),
    ("invalid UTF-8 body", "POST", "/v1/simulations",
     {"content": b"\xff\xfe{", "headers": {"content-type": "application/json"}}, (400, 422),
     None),
    ("snap of a subnormal duration (fuzz)", "POST", "/v1/snaps",
     {"json": {"dmu": 0.5, "duration": 5e-324, "model": "euler-beam"}}, (422,), None),
    ("idempotency key too long", "POST", "/v1/signals",
     {"json": {"dt": 0.1, "w": W}, "headers": {"idempotency-key": "k" * 300}}, (422,),
     "idempotency-key"),
]
