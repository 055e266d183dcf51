"""Numbers as a scientist writes them (``service.numfmt``): hand-worked cases."""

from __future__ import annotations

import math

from service import numfmt


def test_a_value_is_written_to_the_place_of_its_uncertainty() -> None:
    # the page: 30.99993318 deg for an interval of +-3e-4 -> 30.99993 (u = 0.00030)
    assert numfmt.fmt(30.99993318, 3e-4) == "30.99993"
    assert numfmt.fmt_pm(30.99993318, 3e-4) == "30.99993 +- 0.00030"
    assert numfmt.fmt(42.3, 1.7) == "42.3" and numfmt.fmt(42.26, 17.0) == "42"
    assert numfmt.fmt(1234.5, 260.0) == "1230"  # u = 260: to the tens
    assert numfmt.fmt(math.nan, 1.0) == "-" and numfmt.fmt(None) == "-"
    assert numfmt.fmt(1 / 3) == "0.333333"  # no uncertainty: 6 significant digits


def test_interval_ends_round_outward_and_a_safe_value_down() -> None:
    lo, hi = numfmt.fmt_interval(41.99987, 42.00049)  # half-width 3.1e-4: 5 decimals
    assert (lo, hi) == ("41.99987", "42.00049")
    lo, hi = numfmt.fmt_interval(41.999874, 42.000491)
    assert float(lo) <= 41.999874 and float(hi) >= 42.000491
    assert numfmt.fmt_below(41.9999, 0.03) == "41.999"  # never rounded up past a bound
    assert float(numfmt.fmt_below(41.99999, 3e-4)) <= 41.99999


def test_frequencies_in_hz_from_the_time_unit() -> None:
    assert numfmt.hz(2 * math.pi * 12.0, "s") == "12 Hz"
    assert numfmt.hz(2 * math.pi * 0.012, "ms") == "12 Hz"
    assert numfmt.hz(1.0, None) is None and numfmt.hz(1.0, "furlong") is None
