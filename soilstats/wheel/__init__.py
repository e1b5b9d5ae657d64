"""The rigid wheel on soft soil (Wong & Reece 1967) and its prediction over parameter draws.

* :class:`Wheel` — radius, width, grouser shearing radius.
* :func:`wheel_forces` — the Wong–Reece model at a given load (θ1 solved) or sinkage, for
  parameter sets × slips at once: sinkage, drawbar pull, torque.
* :func:`predict_wheel` — posterior/population draws (plus stated priors for what no test
  measured) through the model: predictive bands against slip, a :class:`WheelPrediction`.

Units SI (φ in degrees); conventions and equations in ``docs/wheel.md``.

>>> from soilstats.wheel import Wheel, predict_wheel
>>> wheel = Wheel(radius_m=0.058, width_m=0.05)
>>> pred = predict_wheel(post.draws(4000, seed=1), wheel, 22.0, [0, 0.3, 0.6],
...                      priors={"phi": ("normal", 30, 3), "c": ("uniform", 0, 1000),
...                              "K": ("lognormal", 0.01, 0.5)})        # doctest: +SKIP
>>> print(pred.summary())                                                # doctest: +SKIP
"""

from __future__ import annotations

from .forces import N_NODES, contact_forces
from .geometry import Wheel, entry_angle, sinkage_from_entry_angle, speed_ratio
from .priors import sample_priors
from .propagate import predict_wheel
from .result import QUANTITIES, WheelPrediction
from .solve import STATUS, WheelState, wheel_forces
from .stress import (
    SHEAR_PARAMS,
    SINKAGE_LAWS,
    StressAngles,
    normal_stress,
    pressure_modulus,
    shear_displacement,
    shear_stress,
)

__all__ = [
    "N_NODES",
    "QUANTITIES",
    "SHEAR_PARAMS",
    "SINKAGE_LAWS",
    "STATUS",
    "StressAngles",
    "Wheel",
    "WheelPrediction",
    "WheelState",
    "contact_forces",
    "entry_angle",
    "normal_stress",
    "predict_wheel",
    "pressure_modulus",
    "sample_priors",
    "shear_displacement",
    "shear_stress",
    "sinkage_from_entry_angle",
    "speed_ratio",
    "wheel_forces",
]
