"""The rigid wheel on soft soil (Wong & Reece 1967) and its prediction over parameter draws.

* :class:`Wheel` — radius, width, grouser shearing radius.
* :func:`wheel_forces` — the Wong–Reece model at a given load (θ1 solved) or sinkage, for
  parameter sets × slips at once: sinkage, drawbar pull, torque, and at a slip angle β the
  lateral force (:mod:`.lateral`, :class:`LateralSoil`).
* :func:`predict_wheel` — posterior/population draws (plus stated priors for what no test
  measured) through the model: predictive bands against slip, a :class:`WheelPrediction`.
* :func:`validate_wheel` — measured runs (:func:`read_runs`) against their prediction from
  plate tests only: coverage, bias, what the model gets wrong and the held-out gain of a
  slip-sinkage extension, a :class:`WheelValidation`.

Units SI (φ in degrees); conventions and equations in ``docs/wheel.md``.

>>> from soilstats.wheel import Wheel, predict_wheel
>>> wheel = Wheel(radius_m=0.058, width_m=0.05)
>>> pred = predict_wheel(post.draws(4000, seed=1), wheel, 22.0, [0, 0.3, 0.6],
...                      priors={"phi": ("normal", 30, 3), "c": ("uniform", 0, 1000),
...                              "K": ("lognormal", 0.01, 0.5)})        # doctest: +SKIP
>>> print(pred.summary())                                                # doctest: +SKIP
"""

from __future__ import annotations

from ..bayes.stated_priors import sample_priors
from .forces import N_NODES, contact_forces
from .geometry import Wheel, entry_angle, sinkage_from_entry_angle, speed_ratio
from .lateral import LateralSoil
from .propagate import predict_wheel
from .result import QUANTITIES, WheelPrediction
from .runs import WheelDataError, read_runs, read_wheels
from .slipsinkage import SlipExponent, fit_slip_exponent
from .soil import PlateDraws, plate_draws
from .solve import STATUS, WheelState, wheel_forces
from .stress import (
    PARAM_UNITS,
    SHEAR_PARAMS,
    SINKAGE_LAWS,
    StressAngles,
    normal_stress,
    pressure_modulus,
    shear_displacement,
    shear_stress,
)
from .validation import validate_wheel
from .validation_result import WheelDiscovery, WheelValidation

__all__ = [
    "N_NODES",
    "PARAM_UNITS",
    "QUANTITIES",
    "SHEAR_PARAMS",
    "SINKAGE_LAWS",
    "STATUS",
    "LateralSoil",
    "PlateDraws",
    "SlipExponent",
    "StressAngles",
    "Wheel",
    "WheelDataError",
    "WheelDiscovery",
    "WheelPrediction",
    "WheelState",
    "WheelValidation",
    "contact_forces",
    "entry_angle",
    "fit_slip_exponent",
    "normal_stress",
    "plate_draws",
    "predict_wheel",
    "pressure_modulus",
    "read_runs",
    "read_wheels",
    "sample_priors",
    "shear_displacement",
    "shear_stress",
    "sinkage_from_entry_angle",
    "speed_ratio",
    "validate_wheel",
    "wheel_forces",
]
