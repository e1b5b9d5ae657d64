"""Running emcee: seeding, moves, burn-in and thinning from the measured autocorrelation time.

Procedure (:func:`run_ensemble`):

1. Walkers start at draws of the Laplace approximation N(θ̂, Cov) of the least-squares fit
   (re-drawn where the prior forbids them), so little burn-in is needed.
2. A first ``tune`` steps are run; the integrated autocorrelation time τ of every parameter is
   estimated on them (emcee's estimator, Goodman & Weare / Sokal windowing).
3. Burn-in = ⌈3·τ_max⌉ steps (at least 10) and thinning = max(1, ⌊τ_max/2⌋) are fixed from τ;
   sampling continues until ``draws`` thinned draws (over all walkers) follow the burn-in.
4. If the caller's convergence check (``accept``: R-hat ≤ 1.01, ESS ≥ 400) fails on the kept
   draws, the chain runs on until the kept part is twice as long, at most twice; the same
   check then decides the result's verdict, so a failure is still reported, only rarer.
5. τ is re-estimated on the kept part; if the kept chain is shorter than 50·τ_max (emcee's
   rule of thumb for a reliable τ) this is reported as a diagnostic.

Randomness: one :class:`numpy.random.Generator` seeded from ``seed`` makes the starting
points and the seed of emcee's own ``RandomState`` (passed in through the initial
:class:`emcee.State`, emcee 3's way of seeding a run), so a run is bit-for-bit repeatable.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import emcee
import numpy as np
from tqdm.auto import tqdm

from ..errors import InputError, warn_renamed
from .moves import StudentIndependenceMove

__all__ = ["EnsembleRun", "run_ensemble"]


@dataclass(frozen=True)
class EnsembleRun:
    """Kept draws of an emcee run and how they were chosen."""

    chain: np.ndarray  # (walkers, draws, p) after burn-in and thinning
    log_prob: np.ndarray  # (walkers, draws)
    tau: np.ndarray  # (p,) autocorrelation time in steps, on the kept part before thinning
    burn: int
    thin: int
    steps: int
    acceptance: np.ndarray  # (walkers,) acceptance fraction over the whole run
    runtime_s: float  # wall time of the run [s]
    evaluations: int  # log-probability evaluations (walker-level)
    tau_reliable: bool  # kept chain ≥ 50·τ_max
    extended: int = 0  # times the kept part was doubled because ``accept`` said no

    @property
    def seconds(self) -> float:
        """Renamed :attr:`runtime_s` (docs/conventions.md, "Renamed")."""
        warn_renamed("EnsembleRun.seconds", "EnsembleRun.runtime_s")
        return self.runtime_s


def _start(
    log_prob: Callable[[np.ndarray], np.ndarray],
    centre: np.ndarray,
    cov: np.ndarray,
    n_walkers: int,
    rng: np.random.Generator,
) -> np.ndarray:
    chol = np.linalg.cholesky(cov)
    out = np.empty((n_walkers, centre.size))
    todo = np.arange(n_walkers)
    for _ in range(100):
        trial = centre + rng.standard_normal((todo.size, centre.size)) @ chol.T
        ok = np.isfinite(log_prob(trial))
        out[todo[ok]] = trial[ok]
        todo = todo[~ok]
        if not todo.size:
            return out
        chol = chol * 0.5  # near a prior bound: shrink towards the (allowed) LS estimate
    raise InputError(
        "could not place walkers where the prior allows: the least-squares estimate lies "
        "outside the prior's support — check the priors (or the fit's health flags)"
    )


def run_ensemble(
    log_prob: Callable[[np.ndarray], np.ndarray],
    centre: np.ndarray,
    cov: np.ndarray,
    *,
    draws: int,
    seed: int | None,
    n_walkers: int = 16,
    tune: int = 100,
    progress: bool = False,
    moves: str = "laplace",
    description: str = "sampling",
    accept: Callable[[np.ndarray], bool] | None = None,
    max_extend: int = 2,
    proposal_dof: float = 10.0,
) -> EnsembleRun:
    """Sample ``log_prob`` (vectorised over walkers) with emcee; see the module docstring.

    Parameters
    ----------
    log_prob : callable
        ``log_prob(theta (W, p)) -> (W,)``.
    centre, cov : ndarray
        Laplace approximation (LS estimate and covariance) used for the start and moves.
    draws : int
        Number of kept draws over all walkers (rounded up to a multiple of ``n_walkers``).
    seed : int or None
        Seed of the run (None: fresh entropy, not repeatable).
    moves : {"laplace", "de", "stretch"}
        ``"laplace"``: the Student-t independence move (70 %) mixed with differential
        evolution (30 %); ``"de"``: differential evolution only (DEMove 80 %, DESnookerMove
        20 %, for posteriors without a reliable Laplace approximation); ``"stretch"``:
        emcee's default stretch move (the benchmark's baseline).
    accept : callable, optional
        ``accept(chain (walkers, draws, p)) -> bool``: the convergence check of the kept
        draws.  While it fails, the run continues until the kept part is twice as long, at
        most ``max_extend`` times (so at most 4× the requested draws by default); the final
        verdict is the caller's, and a failure stays a failure.
    max_extend : int
        Most doublings of the kept part.
    proposal_dof : float
        Degrees of freedom ν of the Student-t independence proposal (``moves="laplace"``):
        at most those of the target's tails, so that the importance ratio stays bounded
        (the population model gives T − 1 for T tests).
    """
    centre = np.asarray(centre, float)
    cov = np.asarray(cov, float)
    dim = centre.size
    if n_walkers < 2 * dim:
        raise InputError(f"n_walkers must be at least 2·{dim} = {2 * dim}, got {n_walkers}")
    if draws < 1:
        raise InputError(f"draws must be a positive integer, got {draws}")
    rng = np.random.default_rng(seed)
    mix, independent = _moves(moves, centre, cov, proposal_dof)
    sampler = emcee.EnsembleSampler(n_walkers, dim, log_prob, moves=mix, vectorize=True)
    start = _start(log_prob, centre, cov, n_walkers, rng)
    state = emcee.State(
        start,
        random_state=np.random.RandomState(int(rng.integers(2**32))).get_state(),
    )
    per_walker = math.ceil(draws / n_walkers)
    t0 = time.perf_counter()
    with tqdm(
        total=2 * tune + per_walker,
        desc=description,
        disable=not progress,
        unit="step",
        leave=False,
    ) as bar:

        def advance(start, steps):
            last = start
            for last in sampler.sample(start, iterations=steps, store=True):  # noqa: B007
                bar.update(1)
            return last

        state = advance(state, tune)
        adapted = 0
        if independent is not None:
            # Refit the proposal to the tuning draws (mean and covariance of their second
            # half) when the Laplace approximation is poor; the kept chain starts after this,
            # so it is an ordinary (non-adaptive) Metropolis–Hastings chain.
            recent = sampler.get_chain()[tune // 2 :].reshape(-1, dim)
            independent.refit(recent.mean(axis=0), np.cov(recent, rowvar=False))
            state = advance(state, tune)
            adapted = sampler.iteration
        burn, thin, needed, finite = _burn_and_thin(sampler, adapted, per_walker)
        if not finite:  # no τ: a short unthinned stretch, never extended (_burn_and_thin)
            accept = None
        extended = 0
        while True:
            if needed > sampler.iteration:
                bar.total = needed
                bar.refresh()
                state = advance(state, needed - sampler.iteration)
            if accept is None or extended >= max_extend:
                break
            kept = sampler.get_chain()[burn:][::thin][-per_walker:]
            if accept(np.swapaxes(kept, 0, 1)):
                break
            # Not converged yet: double the kept part (the chain simply runs on; nothing
            # already drawn is discarded or re-weighted), at most ``max_extend`` times.
            per_walker *= 2
            extended += 1
            needed = burn + thin * per_walker
    return _kept(sampler, burn, thin, per_walker, time.perf_counter() - t0, extended)


def _moves(
    moves: str, centre: np.ndarray, cov: np.ndarray, proposal_dof: float
) -> tuple[list | None, StudentIndependenceMove | None]:
    """emcee's move mix of ``moves`` (see :func:`run_ensemble`) and its Student-t
    independence move, refitted after tuning (None where the mix has none)."""
    independent = None
    if moves == "laplace":
        independent = StudentIndependenceMove(centre, cov, dof=proposal_dof)
        mix: list | None = [
            (independent, 0.7),
            (emcee.moves.DEMove(), 0.2),
            (emcee.moves.DESnookerMove(), 0.1),
        ]
    elif moves == "de":
        mix = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    elif moves == "stretch":
        mix = None
    else:
        raise InputError(f"moves must be 'laplace', 'de' or 'stretch', got {moves!r}")
    return mix, independent


def _burn_and_thin(
    sampler: emcee.EnsembleSampler, adapted: int, per_walker: int
) -> tuple[int, int, int, bool]:
    """Burn-in, thinning and the steps needed, from the autocorrelation time τ of the
    chain after adaptation: burn 3τ (at least 10), thin τ/2, at least 50τ kept; and
    whether τ was finite."""
    tau = np.max(emcee.autocorr.integrated_time(sampler.get_chain()[adapted // 2 :], tol=0))
    if math.isfinite(tau):
        burn = adapted + max(10, math.ceil(3 * tau))
        thin = max(1, int(tau / 2))
        return burn, thin, max(burn + thin * per_walker, burn + math.ceil(50 * tau)), True
    # Walkers left the finite part of the density (their values overflowed): there is no
    # autocorrelation time to set a burn-in or a thinning by.  Keep a short stretch,
    # unthinned and not extended; its τ is not finite, so the run is reported as not
    # converged (tau_reliable False) instead of raising here.
    return adapted, 1, adapted + per_walker, False


def _kept(
    sampler: emcee.EnsembleSampler,
    burn: int,
    thin: int,
    per_walker: int,
    runtime_s: float,
    extended: int,
) -> EnsembleRun:
    """The kept draws of a finished run: after ``burn``, every ``thin``-th step, the last
    ``per_walker`` of each walker, with their τ and the run's counts."""
    steps = sampler.iteration
    full = sampler.get_chain()[burn:]  # (steps, walkers, p)
    tau_kept = emcee.autocorr.integrated_time(full, tol=0)
    chain = full[::thin][-per_walker:]
    lp = sampler.get_log_prob()[burn:][::thin][-per_walker:]
    return EnsembleRun(
        chain=np.ascontiguousarray(np.swapaxes(chain, 0, 1)),
        log_prob=np.ascontiguousarray(lp.T),
        tau=np.asarray(tau_kept),
        burn=burn,
        thin=thin,
        steps=steps,
        acceptance=sampler.acceptance_fraction.copy(),
        runtime_s=runtime_s,
        evaluations=steps * sampler.nwalkers,
        tau_reliable=bool(full.shape[0] >= 50 * np.max(tau_kept)),
        extended=extended,
    )
