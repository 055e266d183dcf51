"""The fit cache: every fit of one prediction memoised by its exact inputs.

A :func:`profile_memo` scope (one ``predict`` or ``classify_sweep`` call) opens a
:class:`FitCache`; the fits inside it (:mod:`.likelihood`'s profiles, grid scans, search grids
and window screens, :mod:`.damping`'s damping) look it up with :func:`fit_cache`. Outside a
scope every fit is computed.
"""

from __future__ import annotations

import contextvars
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["FitCache", "fit_cache", "profile_memo"]


class FitCache:
    """The fits of one prediction (or classification), memoised by their exact inputs: the
    value a :func:`profile_memo` scope opens and every fit inside it looks up
    (:func:`fit_cache`). Model selection, the exponent profiles, the interval's refits and the
    damping's search revisit the same windows and laws: each is computed once.

    Entries, by the first element of their key: ``"scan"`` a profile search's grid scan
    (:func:`.likelihood._search`), ``"grid"`` a law's search grid
    (:func:`.likelihood._search_grid`), ``"screen"`` a window's goodness-of-fit screen,
    ``"damping"`` the damping identified on rate data (:func:`.damping.identify_damping`);
    otherwise a profile (:func:`.likelihood.profile`, keyed by :func:`.likelihood._memo_key`).
    Keys hold the inputs' bytes: equal keys are equal inputs, so a hit is the same result to
    the bit. ``hits`` and ``misses`` count the look-ups."""

    __slots__ = ("_entries", "hits", "misses")

    def __init__(self) -> None:
        self._entries: dict[tuple, object] = {}
        self.hits = 0
        self.misses = 0

    def get(self, key: tuple) -> object | None:
        """The entry under ``key`` (None: not computed yet)."""
        hit = self._entries.get(key)
        if hit is None:
            self.misses += 1
        else:
            self.hits += 1
        return hit

    def __contains__(self, key: tuple) -> bool:
        return key in self._entries

    def __getitem__(self, key: tuple) -> object:
        self.hits += 1
        return self._entries[key]

    def __setitem__(self, key: tuple, value: object) -> None:
        self._entries[key] = value

    def __len__(self) -> int:
        return len(self._entries)

    def kinds(self) -> dict[str, int]:
        """Number of entries per kind (``"profile"`` for the profiles)."""
        out: dict[str, int] = {}
        for key in self._entries:
            kind = key[0] if key and isinstance(key[0], str) else "profile"
            out[kind] = out.get(kind, 0) + 1
        return out


_MEMO: contextvars.ContextVar[FitCache | None] = contextvars.ContextVar(
    "profile_memo", default=None
)


def fit_cache() -> FitCache | None:
    """The :class:`FitCache` of the enclosing :func:`profile_memo` scope (None outside one:
    every fit is computed)."""
    return _MEMO.get()


@contextmanager
def profile_memo() -> Iterator[FitCache]:
    """Scope (one ``predict`` or ``classify_sweep`` call) inside which equal fits are computed
    once: yields its :class:`FitCache`; nested scopes share the outer one, and nothing
    outlives the outermost."""
    outer = _MEMO.get()
    if outer is not None:
        yield outer
        return
    cache = FitCache()
    token = _MEMO.set(cache)
    try:
        yield cache
    finally:
        _MEMO.reset(token)
