"""Shared result vocabulary of the analysis layer: flags and the warning class."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


class SnapwarnWarning(UserWarning):
    """A result is usable but doubtful (noise, short record, overdamped mode...)."""


@dataclass(frozen=True)
class Flag:
    """A machine-readable reason to doubt a result.

    Attributes
    ----------
    code : str
        Stable snake_case identifier (e.g. ``"few_periods"``, ``"low_snr"``, ``"overdamped"``).
    message : str
        One human sentence with the numbers that triggered it.
    """

    code: str
    message: str


def unique_flags(flags: Iterable[Flag]) -> list[Flag]:
    """``flags`` in order, each code once (its first occurrence kept)."""
    seen: set[str] = set()
    out = []
    for f in flags:
        if f.code not in seen:
            seen.add(f.code)
            out.append(f)
    return out
