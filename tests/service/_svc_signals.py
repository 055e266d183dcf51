"""Synthetic test signals (a damped oscillation about a static level) and file encoders."""

from __future__ import annotations

import io

import numpy as np


def ringdown(
    n: int = 4000,
    dt: float = 0.01,
    *,
    f: float = 1.3,
    zeta_rate: float = 0.05,
    static: float = 0.3,
    noise: float = 1e-3,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * dt
    rng = np.random.default_rng(seed)
    w = static + np.exp(-zeta_rate * t) * np.sin(2 * np.pi * f * t) + noise * rng.standard_normal(n)
    return t, w


def csv_bytes(t: np.ndarray, w: np.ndarray, header: str = "time [s],w [mm]") -> bytes:
    out = io.StringIO()
    out.write(header + "\n")
    np.savetxt(out, np.column_stack([t, w]), delimiter=",", fmt="%.17g")
    return out.getvalue().encode()


def npy_bytes(a: np.ndarray) -> bytes:
    out = io.BytesIO()
    np.save(out, a)
    return out.getvalue()


def npz_bytes(**arrays: np.ndarray) -> bytes:
    out = io.BytesIO()
    np.savez(out, **arrays)
    return out.getvalue()


def wav_bytes(rate: int, data: np.ndarray) -> bytes:
    from scipy.io import wavfile

    out = io.BytesIO()
    wavfile.write(out, rate, data)
    return out.getvalue()


def mat_bytes(**arrays: np.ndarray) -> bytes:
    from scipy.io import savemat

    out = io.BytesIO()
    savemat(out, arrays)
    return out.getvalue()
