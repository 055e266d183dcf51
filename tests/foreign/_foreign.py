"""Files written the way labs write them, from a known truth (helpers of tests/foreign).

Every record is a damped sine ``exp(-XI t) cos(OMEGA t + 0.3)`` sampled at 1 kHz (plus
optional noise), so the detector's answer can be compared with ``OMEGA`` itself; every sweep
is the exact Euler-beam ``sigma^2`` (``sim.euler_beam.spectrum``) on a lab's fixed grid.
"""

from __future__ import annotations

import datetime
import io
from pathlib import Path

import numpy as np

F0 = 7.0  # Hz
OMEGA = 2.0 * np.pi * F0  # rad/s: the truth
XI = 0.8  # 1/s
DT = 1e-3  # s
N = 4000


def ringdown(noise: float = 1e-3, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(t [s], w)``: the damped sine with white noise of standard deviation ``noise``."""
    t = DT * np.arange(N)
    rng = np.random.default_rng(seed)
    return t, np.exp(-XI * t) * np.cos(OMEGA * t + 0.3) + noise * rng.standard_normal(N)


def table(header: str, cols: list[np.ndarray], fmts: list[str], sep: str = ",") -> str:
    """A header line and the rows, each cell written with its own %-format."""
    rows = [sep.join(f % v for f, v in zip(fmts, row)) for row in zip(*cols)]
    return header + "\n" + "\n".join(rows) + "\n"


def npz(**arrays: object) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    return buf.getvalue()


def npz_positional(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, a)
    return buf.getvalue()


def mat(**arrays: object) -> bytes:
    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, arrays)
    return buf.getvalue()


def lab_records(d: Path) -> dict[str, tuple[Path, float]]:
    """Record files as labs write them: ``name -> (path, expected omega in the file's time
    unit)``. None of these layouts is in tests/recordings or tests/contract."""
    t, w = ringdown()
    out: dict[str, tuple[Path, float]] = {}

    def put(name: str, data: bytes, omega: float = OMEGA) -> None:
        (d / name).write_bytes(data)
        out[name] = (d / name, omega)

    body = table("time_s,w_mm", [t, w], ["%.6f", "%.6e"])
    put("comments.csv", ("# logger v2.1\n# rate: 1 kHz\n\n" + body).encode())
    put("units_row.csv", table("time,w\ns,mm", [t, w], ["%.6f", "%.6e"]).encode())
    scope = table("Time,Channel A\n(ms),(V)", [1e3 * t, w], ["%.4f", "%.6e"])
    put("scope.csv", scope.encode(), OMEGA * 1e-3)  # rad/ms
    excel = table("Time [s]\tDisplacement [mm]", [t, w], ["%.6f", "%.6e"], sep="\t")
    put("excel_unicode.txt", excel.encode("utf-16"))  # Excel's "Unicode text": UTF-16 + BOM
    legacy = table("t [s];Weg [µm]", [t, w], ["%.6f", "%.6e"], sep=";")
    put("legacy.csv", legacy.replace(".", ",").encode("cp1252"))  # decimal commas, cp1252
    put("named.npz", npz(time=t, displacement=w))
    put("logger.npz", npz(timestamps=t, data=w))
    put("table.npz", npz_positional(np.column_stack([t, w])))
    put("rate.npz", npz(w=w, fs=1000.0))
    put("daq.mat", mat(y=w.reshape(-1, 1), Fs=1000.0))
    put("UPPER.CSV", table("T,W", [t, w], ["%.6f", "%.6e"]).replace("\n", "\r\n").encode())
    put("excel_sep.csv", ("sep=;\n" + table("t;w", [t, w], ["%.6f", "%.6e"], sep=";")).encode())
    put("struct.mat", mat(run={"t": t, "w": w}))
    # Unix times at 10 kHz stored as float64 (their spacing: 2.4e-7 s, 2.4e-3 of a step)
    k = np.arange(20000)
    buf = io.BytesIO()
    te = k / 1e4
    np.save(buf, np.column_stack([1.7e9 + te, np.exp(-2.5 * te) * np.cos(628.0 * te)]))
    put("epoch.npy", buf.getvalue(), 628.0)
    # a scope's pre-trigger (20 % of the record at rest before the kick), and a release: the
    # strip held at a static deflection, let go into its free decay about a new equilibrium
    rest = 1e-3 * np.random.default_rng(4).standard_normal(1000)
    tp = DT * np.arange(N + 1000)
    put("pretrigger.csv", table("t [s],w [mm]", [tp, np.r_[rest, w]], ["%.6f", "%.6e"]).encode())
    held = 2.0 + rest
    freed = 0.5 + 1.5 * np.exp(-XI * t) * np.cos(OMEGA * t) + (w - ringdown(0.0)[1])
    put("release.csv", table("t [s],w [mm]", [tp, np.r_[held, freed]], ["%.6f", "%.6e"]).encode())
    # numpy.savetxt's header: the last comment line ("# t w", "# t [s],w [mm]")
    for name, kw in (("savetxt.txt", {}), ("savetxt.csv", {"delimiter": ","})):
        buf = io.BytesIO()
        head = "t w" if not kw else "t [s],w [mm]"
        np.savetxt(buf, np.column_stack([t, w]), header=head, **kw)  # type: ignore[arg-type]
        put(name, buf.getvalue())
    # a logger's clock: ISO 8601 date-times (microseconds; milliseconds with a zone), and
    # times of day across midnight
    start = datetime.datetime(2026, 11, 27, 23, 59, 59, 500000)
    stamps = [start + datetime.timedelta(seconds=float(x)) for x in t]
    iso = "\n".join(f"{s.isoformat()},{v:.6e}" for s, v in zip(stamps, w, strict=True))
    put("iso.csv", f"time,w\n{iso}\n".encode())
    zoned = "\n".join(f"{s.isoformat(' ', 'milliseconds')}+01:00;{v:.6e}"
                      for s, v in zip(stamps, w, strict=True))  # fmt: skip
    put("iso_zone.csv", f"Timestamp;w [mm]\n{zoned}\n".encode())
    tod = "\n".join(f"{s.strftime('%H:%M:%S.%f')[:-3]},{v:.6e}"
                     for s, v in zip(stamps, w, strict=True))  # fmt: skip
    put("time_of_day.csv", f"time,w\n{tod}\n".encode())
    return out


def bad_records(d: Path) -> dict[str, tuple[Path, str]]:
    """Broken lab files: ``name -> (path, the field the error must name)``."""
    t, w = ringdown()
    out: dict[str, tuple[Path, str]] = {}
    body = table("t,w", [t, w], ["%.6f", "%.6e"]).splitlines()
    body[7] = f"{t[6]:.6f},n/a"  # the 7th data row, on line 4 + 7 = 11 of the file
    text = "# a\n# b\n\n" + "\n".join(body) + "\n"
    (d / "bad_cell.csv").write_text(text)
    out["bad_cell.csv"] = (d / "bad_cell.csv", "file: line 11, column 'w'")
    (d / "rate_conflict.npz").write_bytes(npz(w=w, dt=1e-3, fs=500.0))
    out["rate_conflict.npz"] = (d / "rate_conflict.npz", "file: fs")
    (d / "two_signals.npz").write_bytes(npz(t=t, displacement=w, data=-w))
    out["two_signals.npz"] = (d / "two_signals.npz", "file")
    return out


def beam_grid(act: str, step: float, stop: float, rel: float = 1e-4, seed: int = 0):
    """A lab's fixed grid ``0, step, ...`` up to ``mu* - stop`` with the exact beam sigma^2
    and relative noise ``rel``: ``(mu*, mu, sigma2, sigma2_std)``."""
    from sim.euler_beam import bifurcation, spectrum

    ms = bifurcation(act).mu_star
    mu = np.arange(0.0, ms - stop + 1e-12, step)
    s2 = np.array([spectrum(act, float(m), "U_A", modes=1).sigma2[0] for m in mu])
    sd = rel * np.abs(s2)
    rng = np.random.default_rng(seed)
    return ms, mu, s2 + sd * rng.standard_normal(mu.size), sd
