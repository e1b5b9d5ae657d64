"""Wheel calibration on measured runs with a model-discrepancy term, and its held-out test.

* :mod:`.inputs` — the uncertain inputs (stress angles, exit angle, datum, slip-sinkage,
  c, φ, K) as stated, sourced priors;
* :mod:`.physics` — the wheel model over parameter sets × runs;
* :mod:`.discrepancy` — the Gaussian-process discrepancy in slip and slip angle;
* :mod:`.calibrate` — :func:`calibrate_wheel` (emcee) and :class:`WheelCalibration`;
* :mod:`.heldout` — validation holding out whole slip conditions, slip angles or a wheel,
  beside the no-physics baseline.
"""

from .calibrate import calibrate_wheel
from .discrepancy import Discrepancy, fit_discrepancy
from .inputs import DEFAULT_INPUTS, InputPrior, input_priors
from .physics import RunDesign, simulate
from .result import WheelCalibration, load_calibration

__all__ = [
    "DEFAULT_INPUTS",
    "Discrepancy",
    "InputPrior",
    "RunDesign",
    "WheelCalibration",
    "calibrate_wheel",
    "fit_discrepancy",
    "input_priors",
    "load_calibration",
    "simulate",
]
