"""Bayesian calibration of the wheel on measured runs, with a model-discrepancy term.

:func:`calibrate_wheel` samples, with emcee, the wheel-level inputs of :mod:`.inputs` (stress
angles, exit angle, sinkage datum, slip-sinkage exponent; c, φ, K where drawbar pull is
measured) together with the plate law's parameters, whose prior is the plate posterior (a
multivariate normal fitted to the plate draws on a log scale for positive parameters, sampled
whitened), given the runs' measured sinkage and drawbar pull; the model's remaining error is
the Gaussian-process discrepancy of :mod:`.discrepancy` (Kennedy & O'Hagan 2001), integrated
out of the likelihood.  Procedure:

1. least squares (prior pseudo-observations + runs, a provisional iid error per quantity) for
   the start and its Laplace covariance;
2. each quantity's discrepancy hyperparameters by type-II maximum likelihood of the residuals
   there (held fixed afterwards, Kennedy & O'Hagan's plug-in);
3. emcee (:func:`soilstats.bayes.sampler.run_ensemble`: Laplace start, Student-t independence
   and differential-evolution moves, burn-in and thinning from the autocorrelation time),
   vectorised over walkers × runs; R-hat and ESS checked with ArviZ, a failure is a flag.

The result is a :class:`~.result.WheelCalibration` (:mod:`.result`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.optimize import OptimizeResult, least_squares

from ...bayes._arviz import az
from ...bayes.population import laplace_mode
from ...bayes.sampler import EnsembleRun, run_ensemble
from ...errors import InputError, SoilstatsError
from ...models import get_model
from ..geometry import Wheel
from .discrepancy import Discrepancy, fit_discrepancy, repeat_scatter
from .inputs import SHEAR_INPUTS, WHEEL_INPUTS, input_priors
from .physics import RunDesign, simulate
from .result import Layout, PlatePrior, WheelCalibration, design_inputs, wheel_codes

__all__ = ["ESS_MIN", "FIXED_INPUTS", "RHAT_MAX", "calibrate_wheel"]

#: Smallest error of a measurement (the discrepancy's noise floor) by quantity.
FLOOR = {"sinkage_m": 2e-4, "drawbar_pull_N": 0.1, "lateral_force_N": 0.1}
#: Provisional iid error of the least-squares start, by quantity.
PILOT = {"sinkage_m": 3e-3, "drawbar_pull_N": 2.0, "lateral_force_N": 2.0}
#: Inputs held fixed unless the user states a prior for them: the slope of the exit angle in
#: slip b1 (0: CMU's value at β = 0), which the runs cannot tell from a1 and n1 — sampling it
#: only slowed the sampler (R-hat 1.2 on simulated runs), its posterior staying its prior.
FIXED_INPUTS = {"b1": 0.0}
#: emcee's moves: differential evolution (R-hat 1.03 on the CMU runs where the Student-t
#: independence move of the Laplace approximation gave 1.11 at the same cost).
MOVES = "de"
#: Convergence checks of the posterior (as soilstats.bayes': docs/posterior.md).
RHAT_MAX, ESS_MIN = 1.01, 400


@dataclass(frozen=True, eq=False)
class _Problem:
    """The runs, the model and the layout of one calibration: residuals and log-density."""

    design: RunDesign
    wheels: Mapping[str, Wheel]
    law: str
    layout: Layout
    quantities: tuple[str, ...]
    shear: bool

    def mask(self, q: str) -> np.ndarray:
        return np.isfinite(self.design.measured[q])

    def model(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        """Model outputs (P, R) at the sampling-scale vectors ``theta`` (P, d)."""
        params = self.layout.params(np.atleast_2d(theta))
        return simulate(params, self.design, self.wheels, self.law, with_shear=self.shear)

    def residuals(self, theta: np.ndarray, sigma: Mapping[str, float]) -> np.ndarray:
        """Prior pseudo-observations and the runs' standardised residuals (least squares)."""
        out = self.model(theta)
        parts = [self.layout.prior_residuals(theta)]
        for q in self.quantities:
            m = self.mask(q)
            r = (out[q][0, m] - self.design.measured[q][m]) / sigma[q]
            parts.append(np.where(np.isfinite(r), r, 1e3))
        return np.concatenate(parts)

    def rms(self, theta: np.ndarray) -> dict[str, float]:
        """RMS residual of each quantity at ``theta`` (at least its floor)."""
        out = self.model(theta)
        return {
            q: max(
                float(np.sqrt(np.nanmean((out[q][0, m] - self.design.measured[q][m]) ** 2))),
                FLOOR[q],
            )
            for q in self.quantities
            for m in (self.mask(q),)
        }


def _layout(
    design: RunDesign,
    plate_draws: pd.DataFrame,
    law: str,
    priors: Mapping[str, Sequence] | None,
    shear: bool | None,
    plate_source: str,
) -> tuple[Layout, bool, tuple[str, ...]]:
    """The sampled vector's layout, whether the shear is carried, and the quantities used."""
    names = get_model(law, kind="sinkage").param_names
    plate = PlatePrior.from_draws(plate_draws, names, plate_source)
    stated = input_priors(priors)
    if shear is None:
        shear = "drawbar_pull_N" in design.measured or any(
            k in (priors or {}) for k in ("c", "phi", "K")
        )
    use = WHEEL_INPUTS + (SHEAR_INPUTS if shear else ())
    fixed = {k: v for k, v in FIXED_INPUTS.items() if k not in (priors or {})}
    layout = Layout(plate, tuple(stated[n] for n in use if n not in fixed), tuple(fixed.items()))
    forces = ("drawbar_pull_N", "lateral_force_N")
    quantities = [q for q in design.measured if q not in forces or shear]
    if not np.any(design.beta_deg != 0):  # the model's lateral force is 0 at β = 0
        quantities = [q for q in quantities if q != "lateral_force_N"]
    quantities = [q for q in quantities if np.isfinite(design.measured[q]).sum() >= 5]
    if "sinkage_m" not in quantities:
        raise InputError("a calibration needs measured sinkage (sinkage_m) on at least 5 runs")
    return layout, shear, tuple(quantities)


def _least_squares_start(problem: _Problem) -> OptimizeResult:
    """Prior pseudo-observations + runs with a provisional iid error, re-estimated once."""
    lo, hi = problem.layout.bounds()
    start = np.clip(
        problem.layout.start(),
        np.where(np.isfinite(lo), lo + 1e-6, lo),
        np.where(np.isfinite(hi), hi - 1e-6, hi),
    )
    sigma = {q: PILOT[q] for q in problem.quantities}
    fit = None
    for _ in range(2):
        fit = least_squares(
            problem.residuals, start, args=(sigma,), bounds=(lo, hi), x_scale="jac", max_nfev=400
        )
        start, sigma = fit.x, problem.rms(fit.x[None, :])
    assert fit is not None
    return fit


def _discrepancies(problem: _Problem, start: np.ndarray) -> dict[str, Discrepancy]:
    """Each quantity's discrepancy from the residuals at the start (:mod:`.discrepancy`),
    σ floored at the runs' repeat scatter."""
    design = problem.design
    out = problem.model(start[None, :])
    x = design_inputs(design, wheel_codes(design))
    conditions = np.array(
        [
            f"{w}|{s}|{b}"
            for w, s, b in zip(design.wheel, design.slip_level, design.beta_level, strict=True)
        ]
    )
    disc = {}
    for q in problem.quantities:
        m = problem.mask(q)
        r = design.measured[q][m] - out[q][0, m]
        if not np.all(np.isfinite(r)):
            raise SoilstatsError(
                f"the least-squares start of the wheel calibration cannot carry "
                f"{int(np.sum(~np.isfinite(r)))} of the runs' loads: check the plate law and "
                "the wheel geometry"
            )
        sigma_rep, dof = repeat_scatter(design.measured[q][m], conditions[m])
        floor = max(FLOOR[q], sigma_rep) if dof >= 5 else FLOOR[q]
        disc[q] = fit_discrepancy(q, x[m], r, floor=floor)
    return disc


def _log_density(
    problem: _Problem, disc: Mapping[str, Discrepancy]
) -> Callable[[np.ndarray], np.ndarray]:
    """log p(θ | runs) up to a constant, δ integrated out (Gaussian, covariance K + σ²I),
    vectorised over walkers; −∞ where a run cannot be produced."""
    x = design_inputs(problem.design, wheel_codes(problem.design))
    prec = {q: np.linalg.inv(disc[q].covariance(x[problem.mask(q)])) for q in problem.quantities}

    def log_prob(theta: np.ndarray) -> np.ndarray:
        lp = problem.layout.log_prior(theta)
        ok = np.isfinite(lp)
        if not ok.any():
            return lp
        sim = problem.model(theta[ok])
        ll = np.zeros(int(ok.sum()))
        for q in problem.quantities:
            m = problem.mask(q)
            r = problem.design.measured[q][m][None, :] - sim[q][:, m]
            ll += -0.5 * np.einsum("wi,ij,wj->w", r, prec[q], r)
        lp[ok] = lp[ok] + np.where(np.isfinite(ll), ll, -np.inf)
        return lp

    return log_prob


def _sample(
    log_prob: Callable[[np.ndarray], np.ndarray],
    layout: Layout,
    start: np.ndarray,
    draws: int,
    seed: int,
    progress: bool,
) -> EnsembleRun:
    """emcee from the Laplace approximation of the posterior itself (mode and inverse Hessian
    of ``log_prob``; with δ in the likelihood many inputs stay near their priors, so the
    least-squares covariance would be far too narrow), the prior's variances where it fails."""
    with np.errstate(all="ignore"):  # a walker beyond the support gives NaN, read as -inf
        centre, cov = laplace_mode(log_prob, start, layout.dim)
        if not np.isfinite(log_prob(centre[None])[0]):
            centre = start
        if not (np.all(np.isfinite(cov)) and np.all(np.linalg.eigvalsh(cov) > 0)):
            cov = np.diag(
                np.r_[
                    np.ones(len(layout.plate.names)),
                    [
                        (p.sd if p.sd else (p.high - p.low) / np.sqrt(12.0)) ** 2
                        for p in layout.inputs
                    ],
                ]
            )

        def accept(chain: np.ndarray) -> bool:
            rhat, ess = diagnostics(chain)
            return rhat <= RHAT_MAX and ess >= ESS_MIN

        return run_ensemble(
            log_prob,
            centre,
            cov,
            draws=draws,
            seed=seed,
            n_walkers=max(32, 2 * layout.dim + 2),
            progress=progress,
            description="wheel calibration",
            accept=accept,
            moves=MOVES,
        )


def calibrate_wheel(
    design: RunDesign,
    wheels: Mapping[str, Wheel],
    plate_draws: pd.DataFrame,
    law: str,
    *,
    priors: Mapping[str, Sequence] | None = None,
    shear: bool | None = None,
    draws: int = 2000,
    seed: int = 0,
    progress: bool = False,
    plate_source: str = "plate posterior draws",
) -> WheelCalibration:
    """Calibrate the wheel on ``design``'s measured runs (module docstring).

    ``plate_draws`` are the plate posterior's joint draws of the law's parameters (their
    multivariate normal is the plate law's prior).  ``shear`` (default: when drawbar pull is
    measured or c, φ, K priors are given) carries c, φ, K.  ``draws`` kept draws over all
    walkers.  A sampler that does not converge returns its flags (``converged`` False), which
    every report prints; it is never silent.
    """
    if len(design) < 5:
        raise InputError(f"a calibration needs at least 5 measured runs, got {len(design)}")
    layout, shear, quantities = _layout(design, plate_draws, law, priors, shear, plate_source)
    problem = _Problem(design, wheels, law, layout, quantities, shear)
    fit = _least_squares_start(problem)
    disc = _discrepancies(problem, fit.x)
    run = _sample(_log_density(problem, disc), layout, fit.x, draws, seed, progress)
    rhat_max, ess_min = diagnostics(run.chain)
    flags = []
    if rhat_max > RHAT_MAX:
        flags.append(f"high-r-hat: R-hat {rhat_max:.3f} > {RHAT_MAX}")
    if ess_min < ESS_MIN:
        flags.append(f"low-bulk-ess: bulk ESS {ess_min:.0f} < {ESS_MIN}")
    return WheelCalibration(
        law=law,
        layout=layout,
        chain=run.chain,
        design=design,
        wheels=dict(wheels),
        discrepancy=disc,
        flags=tuple(flags),
        runtime_s=run.runtime_s,
        rhat_max=rhat_max,
        ess_min=ess_min,
    )


def diagnostics(chain: np.ndarray) -> tuple[float, float]:
    """Largest R-hat and smallest bulk ESS over the parameters (ArviZ; walkers as chains)."""
    with warnings.catch_warnings():
        # a short run (fewer draws per walker than walkers) is judged all the same: its
        # R-hat and ESS say it is short
        warnings.filterwarnings("ignore", message="More chains", category=UserWarning)
        data = az.convert_to_dataset(chain)
        rhat = float(np.nanmax(az.rhat(data)["x"].values))
        ess = float(np.nanmin(az.ess(data, method="bulk")["x"].values))
    return rhat, ess if math.isfinite(ess) else 0.0
