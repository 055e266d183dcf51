"""The one unpacked-size guard of the binary formats (NPZ, MAT, NPY, WAV), from their headers.

Every door that reads a file calls :func:`check_unpacked_size` before the file's reader: what
the arrays will take once read is known from the headers (the zip directory and each member's
NPY header; the MAT v5 element tags and dims; the NPY header; the WAV chunks) and refused over
the limit in milliseconds (413); a header that declares less than its data holds (a MAT
variable declared 1x1 whose compressed data inflates to 1.6 GB) or more than the file holds
(an NPY or WAV declaring 2 GB in 100 bytes) is a 422 naming the file; nothing is inflated
beyond what its header declares.
"""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np

from service.recordings._errors import RecordingError, RecordingTooLarge

#: The default bound (bytes) where a caller names none (the API's setting
#: ``SNAPWARN_MAX_DECOMPRESSED_BYTES`` has the same default).
DEFAULT_MAX_UNPACKED = 256 * 1024 * 1024
#: Most arrays in one NPZ.
MAX_MEMBERS = 256
#: Bytes a MAT v5 numeric variable may hold besides its data (flags, dims, name, tags, pads).
_MAT_OVERHEAD = 1024

_MAT_NUMERIC = frozenset({4, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15})  # char, double... uint64


def load_failed(fmt: str, data: bytes, exc: Exception) -> RecordingError:
    """The 422 of a file its reader cannot open."""
    return RecordingError("file", f"{len(data)} bytes", f"is not a valid {fmt} file ({exc})")


def _too_large(data: bytes, total: int, limit: int) -> RecordingTooLarge:
    return RecordingTooLarge(
        "file",
        f"{len(data)} bytes",
        f"unpacks to {total} bytes, over the limit of {limit} "
        "(setting SNAPWARN_MAX_DECOMPRESSED_BYTES)",
    )


def check_unpacked_size(data: bytes, fmt: str, limit: int | None = None) -> None:
    """Refuse ``data`` (format ``fmt``) when its arrays unpack beyond ``limit`` bytes
    (:class:`RecordingTooLarge`) or its headers contradict its data (:class:`RecordingError`),
    from the headers alone. CSV is bounded by its own reader (rows counted as it reads)."""
    limit = DEFAULT_MAX_UNPACKED if limit is None else int(limit)
    if fmt == "npz":
        total = _npz_size(data)
    elif fmt == "npy":
        total = _npy_size(io.BytesIO(data), len(data), "file")
    elif fmt == "mat":
        total = _mat_size(data, limit)
    elif fmt == "wav":
        total = _wav_size(data)
    else:
        return
    if total > limit:
        raise _too_large(data, total, limit)


def _npy_size(fp: io.IOBase, available: int, where: str) -> int:
    """Bytes of the array an NPY stream declares; 422 when it declares more than it holds."""
    fmt = np.lib.format
    try:
        version = fmt.read_magic(fp)
        if version == (1, 0):
            shape, _, dtype = fmt.read_array_header_1_0(fp)
        else:
            shape, _, dtype = fmt.read_array_header_2_0(fp)
    except Exception as exc:  # noqa: BLE001 - not an NPY: np.load names the failure
        raise RecordingError(
            where, f"{available} bytes", f"is not a valid .npy array ({exc})"
        ) from None
    count = 1
    for d in shape:
        count *= int(d)
    nbytes = count * dtype.itemsize
    held = available - fp.tell()
    if not dtype.hasobject and nbytes > held:
        raise RecordingError(
            where,
            f"shape {list(shape)}",
            f"declares {nbytes} bytes of {dtype} but holds {held}: the array is truncated "
            "or its header is wrong",
        )
    return nbytes


def _npz_size(data: bytes) -> int:
    """Bytes an NPZ's arrays take: each member's NPY header against its unpacked size."""
    import zipfile

    try:
        z = zipfile.ZipFile(io.BytesIO(data))
        infos = z.infolist()
    except Exception as exc:  # noqa: BLE001 - not a zip
        raise load_failed(".npz", data, exc) from None
    with z:
        if len(infos) > MAX_MEMBERS:
            raise RecordingTooLarge("file", len(infos), f"holds more than {MAX_MEMBERS} arrays")
        total = sum(i.file_size for i in infos)
        declared = 0
        for info in infos:
            if not info.filename.endswith(".npy"):
                continue
            try:
                with z.open(info) as fp:
                    declared += _npy_size(fp, info.file_size, f"file: {info.filename}")
            except RecordingError:
                raise
            except Exception as exc:  # noqa: BLE001 - a broken member
                raise load_failed(".npz", data, exc) from None
    return max(total, declared)


def _inflate_within(comp: bytes, cap: int) -> int:
    """Bytes ``comp`` inflates to, stopping past ``cap`` (never more inflated)."""
    d = zlib.decompressobj()
    got, buf = 0, comp
    try:
        while buf and got <= cap:
            out = d.decompress(buf, min(1 << 20, cap + 1 - got))
            got += len(out)
            buf = d.unconsumed_tail
            if not out:
                break
    except zlib.error:
        return got
    return got


def _mat_size(data: bytes, limit: int) -> int:
    """Bytes a MAT file's variables take as float64; v5 from its element tags (each compressed
    element inflated only as far as its own header declares), others by scipy's ``whosmat``."""
    fast = _mat5_size(data, limit)
    if fast is not None:
        return fast
    from scipy.io import whosmat

    total = 0
    try:
        for _name, shape, cls in whosmat(io.BytesIO(data)):
            size = int(np.prod([int(d) for d in shape], dtype=object))
            total += size * (16 if "complex" in cls else 8)
    except Exception as exc:  # noqa: BLE001
        raise load_failed(".mat", data, exc) from None
    return total


def _mat5_size(data: bytes, limit: int) -> int | None:
    """:func:`_mat_size` of a plain MAT v5 file; None when it is not one."""
    if len(data) < 136 or data[126:128] not in (b"IM", b"MI"):
        return None
    end = "<" if data[126:128] == b"IM" else ">"
    total, pos = 0, 128
    while pos + 8 <= len(data):
        dtype, nbytes = struct.unpack(end + "II", data[pos : pos + 8])
        start = pos
        pos += 8 + nbytes + (-nbytes % 8 if dtype != 15 else 0)
        if dtype == 15:  # miCOMPRESSED: a miMATRIX element, deflated
            comp = data[start + 8 : pos]
            try:
                head = zlib.decompressobj().decompress(comp, 64)
            except zlib.error:
                return None
        elif dtype == 14:  # miMATRIX, with its tag
            head = data[start : start + 64]
        else:
            continue
        if len(head) < 40 or struct.unpack(end + "I", head[:4])[0] != 14:
            return None
        inner_bytes = struct.unpack(end + "I", head[4:8])[0]
        cls = struct.unpack(end + "I", head[16:20])[0] & 0xFF
        dims_type, dims_bytes = struct.unpack(end + "II", head[24:32])
        if cls not in _MAT_NUMERIC or dims_type != 5 or dims_bytes % 4 or 32 + dims_bytes > 64:
            size = 8 * inner_bytes  # cells, structs, sparse: their bytes, counted as doubles
        else:
            dims = struct.unpack(end + f"{dims_bytes // 4}i", head[32 : 32 + dims_bytes])
            count = 1
            for d in dims:
                count *= max(0, d)
            if inner_bytes > 16 * count + _MAT_OVERHEAD:
                raise RecordingError(
                    "file",
                    f"variable of dims {list(dims)}",
                    f"declares {count} values but holds {inner_bytes} bytes: the MAT file's "
                    "header is wrong",
                )
            size = max(8 * count, inner_bytes)
        if size > limit:
            raise _too_large(data, size, limit)
        if dtype == 15 and _inflate_within(comp, inner_bytes + 8) > inner_bytes + 8:
            raise RecordingError(
                "file",
                f"{len(data)} bytes",
                f"holds a compressed variable that inflates beyond the {inner_bytes + 8} bytes "
                "its header declares",
            )
        total += size
    return total


def _wav_size(data: bytes) -> int:
    """Bytes a WAV's samples take as float64; 422 for a rate of 0 or a data chunk that
    declares more bytes than the file holds (a truncated recording)."""
    if len(data) < 12 or data[:4] not in (b"RIFF", b"RIFX") or data[8:12] != b"WAVE":
        return 0  # not RIFF/WAVE: the reader names the failure
    end = "<" if data[:4] == b"RIFF" else ">"
    pos, bits, total = 12, 0, 0
    while pos + 8 <= len(data):
        cid = data[pos : pos + 4]
        size = struct.unpack(end + "I", data[pos + 4 : pos + 8])[0]
        body = pos + 8
        if cid == b"fmt " and size >= 16 and body + 16 <= len(data):
            rate = struct.unpack(end + "I", data[body + 4 : body + 8])[0]
            bits = struct.unpack(end + "H", data[body + 14 : body + 16])[0]
            if rate == 0:
                raise RecordingError("file: sample rate", 0, "must be > 0 (the WAV's fmt chunk)")
        elif cid == b"data":
            held = len(data) - body
            if size > held:
                raise RecordingError(
                    "file",
                    f"{len(data)} bytes",
                    f"is a truncated WAV: its data chunk declares {size} bytes, {held} are present",
                )
            total += 8 * size // max(1, bits // 8)
        pos = body + size + (size & 1)
    return total
