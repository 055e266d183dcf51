"""Files whose headers lie about their data (the unpacked-size guard's cases)."""

from __future__ import annotations

import functools
import io
import struct
import zlib

import numpy as np


@functools.lru_cache(maxsize=4)
def mat_deflated(n: int, dims: tuple[int, int], honest_length: bool = True) -> bytes:
    """A MAT v5 file whose one compressed double ``w`` holds ``n`` zeros (~1.55 MB on the wire
    for 2e8) and declares ``dims``; the deflate stream is written in chunks, never holding the
    zeros. ``honest_length``: the matrix element's length says ``n`` doubles (else it claims
    one double's size, and the deflate stream holds more)."""
    header = b"MATLAB 5.0 MAT-file, made by the snapwarn tests".ljust(116, b" ")
    header += b"\x00" * 8 + struct.pack("<H", 0x0100) + b"IM"
    sub = struct.pack("<II", 6, 8) + struct.pack("<II", 6, 0)  # array flags: double
    sub += struct.pack("<II", 5, 8) + struct.pack("<ii", *dims)
    sub += struct.pack("<II", 1, 1) + b"w" + b"\x00" * 7  # name
    sub += struct.pack("<II", 9, n * 8)  # miDOUBLE real part: n doubles
    length = len(sub) + n * 8 if honest_length else len(sub) + 8
    inner = struct.pack("<II", 14, length) + sub
    z = zlib.compressobj(9)
    parts = [z.compress(inner)]
    chunk = b"\x00" * (1 << 22)
    left = n * 8
    while left > 0:
        parts.append(z.compress(chunk[: min(left, len(chunk))]))
        left -= len(chunk)
    parts.append(z.flush())
    payload = b"".join(parts)
    return header + struct.pack("<II", 15, len(payload)) + payload


def mat_liar(n: int = 200_000_000, honest_length: bool = True) -> bytes:
    """A MAT v5 file whose compressed double ``w`` declares dims 1x1 but holds ``n`` doubles."""
    return mat_deflated(n, (1, 1), honest_length)


def mat_bomb(uncompressed: int = 1 << 30) -> bytes:
    """A MAT v5 file whose one compressed double vector ``w`` (n x 1, as declared) inflates to
    ``uncompressed`` bytes."""
    n = uncompressed // 8
    return mat_deflated(n, (n, 1))


def npy_liar(n: int = 250_000_000) -> bytes:
    """An NPY whose header declares ``n`` doubles and holds 100 bytes."""
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        out, {"descr": "<f8", "fortran_order": False, "shape": (n,)}
    )
    return out.getvalue() + b"\x00" * 100


def wav(rate: int = 1000, n: int = 64, declared: int | None = None) -> bytes:
    """A mono 16-bit WAV of ``n`` samples; ``declared``: the data chunk's size it claims."""
    data = (np.arange(n) % 100).astype("<i2").tobytes()
    fmt = struct.pack("<HHIIHH", 1, 1, rate, rate * 2, 2, 16)
    size = len(data) if declared is None else declared
    body = b"WAVE" + b"fmt " + struct.pack("<I", 16) + fmt + b"data" + struct.pack("<I", size)
    body += data
    return b"RIFF" + struct.pack("<I", len(body)) + body


def npz_as_npy() -> bytes:
    out = io.BytesIO()
    np.savez(out, w=np.sin(np.arange(100) * 0.1), dt=0.01)
    return out.getvalue()
