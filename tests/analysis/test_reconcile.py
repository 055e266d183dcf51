"""reconcile: the fundamental across a sweep, and records set aside with their reason and name."""

from __future__ import annotations

import math

import numpy as np
import pytest

from service.analysis.common import Flag
from service.analysis.detect import Detection, Fundamental, Mode, detect
from service.analysis.errors import ParameterError
from service.analysis.reconcile import SET_ASIDE, reconcile


def _mode(root: float, gamma: float = 0.05, amp: float = 1.0, sign: float = -1.0) -> Mode:
    s2 = sign * root * root
    om = math.sqrt(max(root * root - gamma * gamma, 0.0)) if sign < 0 else 0.0
    return Mode(om, om / (2 * math.pi), gamma, s2, amp, 0.0, 1e-4, 1e-4, 1e-4 * root,
                1e-3)  # fmt: skip


def _det(*roots: float, signs: tuple[float, ...] | None = None) -> Detection:
    signs = signs or (-1.0,) * len(roots)
    modes = tuple(_mode(r, sign=s) for r, s in zip(roots, signs, strict=True))
    fund = Fundamental(modes[0], 0) if modes else None
    flags = () if modes else (Flag("no_mode", "nothing"),)
    return Detection(modes, fund, 0.1, 1e-3, flags, "varpro", 1e-3, 40.0, 1000, 1e-3)


def _aside(d: Detection) -> list[Flag]:
    return [f for f in d.flags if f.code == SET_ASIDE]


def test_clean_sweep_unchanged():
    dets = [_det(r, 3 * r) for r in (10.0, 9.0, 8.0, 6.0)]
    out = reconcile(dets, np.arange(4.0), names=[f"r{i}.csv" for i in range(4)])
    assert out == tuple(dets)


def test_no_mode_and_growing_set_aside_with_name():
    dets = [_det(10.0), _det(), _det(9.0, signs=(1.0,)), _det(8.0)]
    names = ["a.csv", "b.csv", "c.npz", "d.csv"]
    out = reconcile(dets, np.array([0.0, 1.0, 2.0, 3.0]), names=names)
    assert out[0] == dets[0] and out[3] == dets[3]
    (fb,) = _aside(out[1])
    assert "b.csv" in fb.message and "no mode" in fb.message
    (fc,) = _aside(out[2])
    assert "c.npz" in fc.message and "sigma^2" in fc.message and ">= 0" in fc.message
    # the rest of the detection is kept as it was
    assert out[2].modes == dets[2].modes and out[2].fundamental == dets[2].fundamental


def test_band_moves_the_fundamental_and_sets_aside_outside():
    # a slow drift-like mode at 0.5 below the ringing mode at 10; the band says [5, 20]
    dets = [_det(0.5, 10.0), _det(9.0, 30.0), _det(40.0)]
    out = reconcile(dets, np.arange(3.0), names=["x", "y", "z"], band=(5.0, 20.0))
    assert out[0].fundamental.index == 1
    assert math.isclose(math.sqrt(-out[0].fundamental.sigma2), 10.0)
    assert "fundamental_band" in out[0].flag_codes and not _aside(out[0])
    assert out[1] == dets[1]
    (fz,) = _aside(out[2])
    assert "z" in fz.message and "band" in fz.message


@pytest.mark.parametrize(
    ("kwargs", "param"),
    [
        ({"controls": np.arange(2.0), "names": ["a", "b", "c"]}, "controls"),
        ({"controls": np.array([0.0, np.nan, 1.0]), "names": ["a", "b", "c"]}, "controls"),
        ({"controls": np.arange(3.0), "names": ["a", "b"]}, "names"),
        ({"controls": np.arange(3.0), "names": ["a", "b", "c"], "band": (5.0, 1.0)}, "band"),
        ({"controls": np.arange(3.0), "names": ["a", "b", "c"], "band": "x"}, "band"),
    ],
)
def test_bad_arguments_name_the_field(kwargs, param):
    dets = [_det(1.0)] * 3
    controls = kwargs.pop("controls")
    with pytest.raises(ParameterError) as ei:
        reconcile(dets, controls, **kwargs)
    assert ei.value.parameter == param


def test_real_detections_constant_record_set_aside():
    t = np.arange(2000) * 1e-3
    ring = 0.1 + 1e-3 * np.exp(-0.5 * t) * np.cos(40.0 * t)
    dets = [detect(ring, dt=1e-3), detect(np.full(2000, 0.1), dt=1e-3)]
    out = reconcile(dets, np.array([0.0, 1.0]), names=["ring.csv", "flat.csv"])
    assert out[0] == dets[0]
    (f,) = _aside(out[1])
    assert "flat.csv" in f.message
