"""Samples of a posterior on the unit cube: emcee's ensemble sampler (Foreman-Mackey et al. 2013), and what says
whether its chains can be trusted.

The moves: differential evolution (ter Braak 2006) 80 % of the time, its snooker variant (ter Braak & Vrugt
2008) 20 % (the mixture emcee's documentation suggests).  Measured on the tiny twin's surrogate posterior
(correlation 0.95, cut by its box): autocorrelation times of 26-36 steps, against 74-103 with emcee's default
stretch move at the same cost per step, i.e. a third of the steps for the same effective sample size.

The log-probability takes many points at once (emcee's `vectorize`: the surrogate predicts a half-ensemble in
one call).  The integrated autocorrelation time tau of each coordinate is emcee's estimate (Sokal's window);
the first `BURN` tau of every chain are discarded, the rest thinned by tau / 2.  The chains are trusted when
they are at least `LONG` tau long (emcee's documentation asks for 50) and the mean acceptance fraction lies
in `ACCEPTANCE` (measured 0.3 for these moves on a correlated Gaussian in two dimensions; far below, the
walkers hardly move); otherwise `verdicts` says so in words.  The
effective sample size of a coordinate is walkers x (kept steps) / tau.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

BURN = 3.0  # autocorrelation times discarded at the start of every chain
LONG = 50.0  # chains this many autocorrelation times long are taken as converged
ACCEPTANCE = (0.15, 0.9)


@dataclass(frozen=True)
class Chains:
    """What the sampler kept, and how far to trust it."""

    samples: np.ndarray  # kept samples x coordinates (burn-in discarded, thinned)
    acceptance: float  # mean acceptance fraction over the walkers
    autocorrelation: np.ndarray  # integrated autocorrelation time per coordinate, in steps
    effective: np.ndarray  # effective sample size per coordinate
    steps: int
    walkers: int
    burn: int
    thin: int

    @property
    def converged(self) -> bool:
        return bool(np.all(self.steps >= LONG * self.autocorrelation)) and np.all(np.isfinite(self.autocorrelation))

    def verdicts(self, names: list[str]) -> list[str]:
        """Plain words when the chains cannot be trusted (empty when they can)."""
        said = []
        short = [f"{n} (tau = {t:.3g} steps)" for n, t in zip(names, self.autocorrelation)
                 if not self.steps >= LONG * t]
        if short:
            said.append(f"the chains have not converged: {self.steps} steps are fewer than {LONG:g} autocorrelation "
                        f"times of {', '.join(short)}: raise [method] steps")
        low, high = ACCEPTANCE
        if not low <= self.acceptance <= high:
            said.append(f"the sampler's acceptance fraction {self.acceptance:.2f} lies outside {low}-{high}: "
                        "its chains mix poorly (a posterior of several modes, or one confined to a corner)")
        return said


def sample(log_probability: Callable[[np.ndarray], np.ndarray], start: np.ndarray, steps: int,
           seed: int) -> Chains:
    """Run emcee from `start` (walkers x coordinates, every one where the log-probability is finite) for `steps`
    steps; deterministic for a given seed."""
    import emcee  # lazily: only a posterior calibration samples

    walkers, k = start.shape
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(walkers, k, log_probability, vectorize=True, moves=moves)
    sampler.random_state = np.random.RandomState(seed).get_state()
    with threadpool_limits(1, user_api="blas"):  # small matrices: one thread (`surrogate`)
        sampler.run_mcmc(start, steps, progress=False)
    tau = np.asarray(sampler.get_autocorr_time(tol=0, quiet=True), dtype=float)
    finite = tau[np.isfinite(tau)]
    longest = float(finite.max()) if finite.size else steps / LONG
    burn = min(int(math.ceil(BURN * longest)), steps // 2)
    thin = max(1, int(float(finite.min()) / 2) if finite.size else 1)
    kept = sampler.get_chain(discard=burn, thin=thin, flat=True)
    effective = walkers * (steps - burn) / tau
    return Chains(kept, float(np.mean(sampler.acceptance_fraction)), tau, effective, steps, walkers, burn, thin)


def quantiles(samples: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per coordinate: the median and the 2.5 % and 97.5 % quantiles (a central 95 % credible interval)."""
    low, median, high = np.quantile(samples, [0.025, 0.5, 0.975], axis=0)
    return median, low, high
