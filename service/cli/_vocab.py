"""The command line's vocabulary (argparse ``choices``), without importing what defines it.

Building the parser must not import numpy, pydantic or the numerics: ``snapwarn --help`` and
every command pay for the parser, only the command that runs pays for its own imports. The
names below are those of their owners (``sim.scene``, ``sim.backends``,
``service.schemas.predictions``, ``service.recordings``); ``tests/test_cli_imports.py``
checks that they stay equal.
"""

from __future__ import annotations

#: ``sim.scene.ACTUATIONS``
ACTUATIONS: tuple[str, ...] = ("asymmetric", "symmetric", "antisymmetric")
#: ``sim.scene.BRANCHES``
BRANCHES: tuple[str, ...] = ("U_A", "U_B", "S_A", "S_B", "W_A", "W_B")
#: ``sim.scene.MODELS``: the simulators and "auto"
MODELS: tuple[str, ...] = ("normal-form", "euler-beam", "cosserat", "auto")
#: ``tuple(sim.backends.BACKENDS)``: the simulators with statics (no "auto")
STATIC_MODELS: tuple[str, ...] = ("normal-form", "euler-beam", "cosserat")
#: ``service.schemas.predictions.PREDICT_TRANSITIONS``
PREDICT_TRANSITIONS: tuple[str, ...] = (
    "saddle-node", "subcritical-pitchfork", "supercritical-pitchfork", "pitchfork"
)
#: ``service.recordings.FORMATS``
RECORDING_FORMATS: tuple[str, ...] = ("csv", "npy", "npz", "wav", "mat")
