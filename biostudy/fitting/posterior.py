"""The posterior of the parameters given the data, sampled on a Gaussian-process surrogate of the simulator.

Why a surrogate: emcee needs ~1e4 evaluations of the likelihood for two parameters; one simulation of the
bundled example takes ~0.6 s, so directly on the simulator that is hours (docs/calibration.md).  The route:

1. The box: the least-squares estimate ± `box` of its standard errors (Jacobian) per coordinate of the unit
   cube, cut to the bounds (the whole range of a coordinate whose standard error is not finite).  The
   likelihood is taken as zero outside it: in the local approximation chi² there is at least `box`² above
   its minimum.  The Jacobian's standard errors can understate an asymmetric posterior (measured on the
   bundled example: the box cut g's lower tail), so where the first pass (3.) finds the posterior's density
   at a face that is not a bound still above `EDGE_DENSITY` of its peak, that side's distance from the estimate
   is doubled, `design` / 2 more simulations fill the wider box, and 2.-3. are repeated (at most `WIDENINGS`
   times); still cut after that, `verdicts` says so.
4. Refinement: `design` / 2 more simulations at points drawn from that first posterior (where the surrogate
   must be good) join the training, and a first pass is made again, now on the marginal likelihood of the
   GP's prediction: log L = -1/2 sum_i [m_i(u)² / (1 + v_i(u)) + log(1 + v_i(u))].  Without the refinement,
   and with the held-out points drawn from the unnormalised pass, the tiny test twin's held-out error reached
   4-6 sigma: those points fell where the GP was unsure (a corner of a box widened to most of the range).
5. Held out: `held_out` simulations at points drawn from that second first pass (where its error matters),
   not used for training; per residual the root-mean-square error e_i of the surrogate's mean there.
6. The posterior: emcee on log L = -1/2 sum_i m_i(u)² / (1 + e_i²): the measured surrogate error added to the
   measurement variance, sigma_i² -> sigma_i² + (sigma_i e_i)²; prior uniform on the unit cube of the bounds
   (log-uniform in a log parameter's own units).
7. The band: the surrogate's mean of every observable at the data times over the posterior samples, its
   2.5 % and 97.5 % quantiles (the model's band, the measurement noise not added).

Every simulation is asked for through the `Objective` (points -> weighted residuals, None for a failed run), so
the command's case files and fingerprints serve here as in least squares, and the fit's own simulations inside
the box join the training.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import qmc

from .objective import Objective, key
from .sampling import Chains, sample
from .surrogate import HeldOut, Surrogate, held_out, train

SMALL = 0.3  # the surrogate's held-out error (units of sigma) beyond which it is said to widen the posterior
EDGE_BINS = 20  # the posterior's density per twentieth of the box ...
EDGE_DENSITY = 0.02  # ... at a face above this share of its peak: the box cuts the posterior (a Gaussian: < 2.8 SE)
BAND_SAMPLES = 1000
WIDENINGS = 3  # times the box may be widened where the first pass finds the posterior cut by it
FIRST_STEPS = 200  # the first pass only picks the held-out points: a quarter of the steps, at least these


@dataclass(frozen=True)
class Options:
    design: int = 30
    held_out: int = 8
    walkers: int = 16
    steps: int = 2000
    box: float = 6.0
    seed: int = 0


@dataclass
class Posterior:
    """What sampling found, and what it rests on."""

    chains: Chains
    surrogate: Surrogate
    held: HeldOut
    low: np.ndarray  # the box (unit cube)
    high: np.ndarray
    inflation: np.ndarray  # e_i² per residual: added to 1 (sigma²) in the likelihood
    trained_on: int  # simulations the surrogate was trained on
    designed: int  # of which the design's (the first and those of every widening)
    widened: int  # times the box was widened
    from_fit: int  # of which the least-squares fit's own
    failed: int  # design or held-out simulations that failed (left out)
    band: np.ndarray  # 2 x residuals: the 2.5 % and 97.5 % quantiles of the predicted residuals
    first: Chains  # the first pass (held-out points drawn from it)
    verdicts: list[str] = field(default_factory=list)
    seconds: float = 0.0  # wall time of the surrogate and the sampler (the simulations not included)


def box(centre: np.ndarray, standard_error: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """centre ± width standard errors, cut to [0, 1]; [0, 1] where a standard error is not finite."""
    se = np.where(np.isfinite(standard_error), standard_error, np.inf)
    low = np.clip(centre - width * se, 0.0, 1.0)
    high = np.clip(centre + width * se, 0.0, 1.0)
    narrow = high - low < 1e-3
    return np.where(narrow, np.clip(centre - 5e-4, 0, 1), low), np.where(narrow, np.clip(centre + 5e-4, 0, 1), high)


def _inside(u: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    return np.all((u >= low) & (u <= high), axis=-1)


def _starts(centre, standard_error, low, high, walkers, rng) -> np.ndarray:
    """Walkers in a small ball around the least-squares estimate (a quarter of a standard error), inside the box."""
    spread = np.where(np.isfinite(standard_error), 0.25 * standard_error, 0.1 * (high - low))
    spread = np.minimum(spread, 0.1 * (high - low))
    inner = low + 1e-6 * (high - low), high - 1e-6 * (high - low)
    return np.clip(centre + spread * rng.standard_normal((walkers, len(centre))), *inner)


def _edges(samples: np.ndarray, low: np.ndarray, high: np.ndarray,
           bounds: bool = False) -> list[tuple[int, int, float]]:
    """(coordinate, -1 lower / +1 upper, density there / peak) of every face of the box where the samples'
    density is still more than `EDGE_DENSITY` of its peak: faces that are not bounds (the box cuts the
    posterior there), or with `bounds` those that are (the data do not bound the parameter there: the prior's
    range does)."""
    found = []
    for j in range(samples.shape[1]):
        counts = np.histogram(samples[:, j], bins=EDGE_BINS, range=(low[j], high[j]))[0]
        for face, bound, count, side in ((low[j], 0.0, counts[0], -1), (high[j], 1.0, counts[-1], 1)):
            if (face == bound) == bounds and count > EDGE_DENSITY * counts.max():
                found.append((j, side, float(count / counts.max())))
    return found


def _cut(samples: np.ndarray, low: np.ndarray, high: np.ndarray) -> list[tuple[int, int]]:
    """(coordinate, -1 lower / +1 upper) of every face of the box, not a bound, that cuts the posterior."""
    return [(j, side) for j, side, _ in _edges(samples, low, high)]


def _first_pass(training: dict, low: np.ndarray, high: np.ndarray, centre: np.ndarray, standard_error: np.ndarray,
                options: Options, rng: np.random.Generator, normalised: bool) -> tuple[Surrogate, Chains]:
    """The surrogate trained on `training` (key -> (point, residuals)) in the box, and a first pass on it (steps 3
    and 4 of the module docstring; `normalised`: with the term -1/2 log(1 + v))."""
    points = np.array([p for p, _ in training.values()])
    residuals = np.array([r for _, r in training.values()])
    surrogate = train(points, residuals, low, high)

    def log_probability(u: np.ndarray) -> np.ndarray:
        mean, variance = surrogate.predict(u)
        total = 1.0 + variance
        value = -0.5 * np.sum(mean**2 / total + (np.log(total) if normalised else 0.0), axis=1)
        return np.where(_inside(u, low, high), value, -np.inf)

    start = _starts(centre, standard_error, low, high, options.walkers, rng)
    return surrogate, sample(log_probability, start, max(FIRST_STEPS, options.steps // 4), options.seed)


@dataclass
class _Training:
    """The surrogate's training runs (key -> point, residuals), and what they cost."""

    runs: dict[tuple, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    designed: int = 0  # of the design's (the first, every widening's and the refinement's)
    from_fit: int = 0  # of least squares' own
    failed: int = 0  # design or held-out runs that failed (left out)
    seconds: float = 0.0  # wall time of the surrogates and the first passes

    def add(self, points: np.ndarray, results: list) -> None:
        self.failed += sum(r is None for r in results)
        self.designed += sum(r is not None for r in results)
        self.runs.update({key(p): (p, np.asarray(r)) for p, r in zip(points, results) if r is not None})

    def take(self, known: list[tuple[np.ndarray, np.ndarray | None]], low: np.ndarray, high: np.ndarray) -> None:
        """The fit's own simulations inside the box join the training."""
        for point, result in known:
            if result is not None and key(point) not in self.runs and _inside(point, low, high):
                self.runs[key(point)] = (np.asarray(point), np.asarray(result))
                self.from_fit += 1

    @contextmanager
    def timed(self):
        began = time.perf_counter()
        yield
        self.seconds += time.perf_counter() - began


def _fill_box(objective: Objective, centre: np.ndarray, standard_error: np.ndarray, options: Options,
              rng: np.random.Generator, training: _Training):
    """Steps 1-3: the design in the box, the first pass on its surrogate, the box widened where the first pass
    finds it cutting the posterior; returns the box, the last first pass and how often it was widened."""
    low, high = box(centre, standard_error, options.box)
    known = objective.known()
    count = options.design
    for widening in range(WIDENINGS + 1):
        design = low + (high - low) * qmc.LatinHypercube(d=objective.k, scramble=True,
                                                         rng=options.seed + widening).random(count)
        ran = objective.evaluate(list(design))
        training.take(known, low, high)
        training.add(design, ran)
        with training.timed():
            _, first = _first_pass(training.runs, low, high, centre, standard_error, options, rng, False)
        cut = _cut(first.samples, low, high)
        if not cut or widening == WIDENINGS:
            break
        for j, side in cut:  # that side's distance from the estimate doubled, within the bounds
            if side < 0:
                low[j] = max(0.0, centre[j] - 2 * (centre[j] - low[j]))
            else:
                high[j] = min(1.0, centre[j] + 2 * (high[j] - centre[j]))
        count = max(objective.k + 2, options.design // 2)
    return low, high, first, widening


def _held_out(objective: Objective, surrogate: Surrogate, picked: np.ndarray, training: _Training,
              verdicts: list[str]) -> tuple[HeldOut, np.ndarray]:
    """Step 5: the surrogate's error on runs it was not trained on, and the variance it adds per residual."""
    answers = objective.evaluate(list(picked))
    training.failed += sum(r is None for r in answers)
    good = [(p, r) for p, r in zip(picked, answers) if r is not None]
    with training.timed():
        if good:
            held = held_out(surrogate, np.array([p for p, _ in good]), np.array([r for _, r in good]))
            return held, held.error**2
        _, variance = surrogate.predict(picked)
    verdicts.append("no held-out simulation succeeded: the surrogate's error is its own predicted variance, "
                    "not measured")
    residuals = next(iter(training.runs.values()))[1]
    return HeldOut(np.full(len(residuals), np.nan), np.sqrt(np.mean(variance, axis=0)), 0), np.mean(variance, axis=0)


def _statements(chains: Chains, inflation: np.ndarray, low: np.ndarray, high: np.ndarray, widening: int,
                options: Options, names: tuple[str, ...]) -> list[str]:
    """What the sampler, the surrogate's error and the box say about the posterior, in words."""
    said = chains.verdicts(list(names))
    worst = float(np.sqrt(np.max(inflation)))
    if worst > SMALL:
        said.append(f"the surrogate's error on held-out simulations reaches {worst:.2g} sigma (measurement "
                    f"{int(np.argmax(inflation)) + 1} of the table): not small against the data's noise, it "
                    f"widens the posterior (sigma inflated by up to {100 * (np.sqrt(1 + worst**2) - 1):.0f} %), "
                    "and more training runs ([method] design) would shrink it")
    for j, side, share in _edges(chains.samples, low, high):
        said.append(f"the posterior of {names[j]} reaches the {'lower' if side < 0 else 'upper'} edge of the "
                    f"surrogate's box (widened {widening} times from {options.box:g} standard errors of least "
                    f"squares), where its density is still {100 * share:.0f} % of its peak: "
                    "widen it ([method] box)")
    for j, side, share in _edges(chains.samples, low, high, bounds=True):
        said.append(f"the posterior of {names[j]} reaches its {'lower' if side < 0 else 'upper'} bound "
                    f"([estimate]), where its density is still {100 * share:.0f} % of its peak: the data do not "
                    f"bound {names[j]} on that side, so its credible interval there is the prior's range, not "
                    "the data's (the profile likelihood, profiles = true, says whether the data determine it)")
    return said


def posterior(objective: Objective, centre: np.ndarray, standard_error: np.ndarray, options: Options) -> Posterior:
    """Sample the posterior (module docstring): `centre`, `standard_error` the least-squares estimate and its
    standard errors (unit cube); the objective's simulations so far inside the box join the training."""
    centre, standard_error = np.asarray(centre, float), np.asarray(standard_error, float)
    rng = np.random.default_rng(options.seed)
    training = _Training()
    low, high, first, widening = _fill_box(objective, centre, standard_error, options, rng, training)
    # refinement: runs where the first posterior lies, trained on too; the held-out runs are drawn after it
    refined = first.samples[rng.choice(len(first.samples), size=min(max(objective.k + 2, options.design // 2),
                                                                    len(first.samples)), replace=False)]
    training.add(refined, objective.evaluate(list(refined)))
    with training.timed():
        surrogate, first = _first_pass(training.runs, low, high, centre, standard_error, options, rng, True)
    picked = first.samples[rng.choice(len(first.samples), size=min(options.held_out, len(first.samples)),
                                      replace=False)]
    verdicts: list[str] = []
    held, inflation = _held_out(objective, surrogate, picked, training, verdicts)

    def log_probability(u: np.ndarray) -> np.ndarray:
        mean, _ = surrogate.predict(u, variance=False)
        value = -0.5 * np.sum(mean**2 / (1.0 + inflation), axis=1)
        return np.where(_inside(u, low, high), value, -np.inf)

    with training.timed():
        start = _starts(centre, standard_error, low, high, options.walkers, rng)
        chains = sample(log_probability, start, options.steps, options.seed + 1)
        shown = chains.samples[rng.choice(len(chains.samples), size=min(BAND_SAMPLES, len(chains.samples)),
                                          replace=False)]
        band = np.quantile(surrogate.predict(shown, variance=False)[0], [0.025, 0.975], axis=0)
    verdicts += _statements(chains, inflation, low, high, widening, options, objective.names)
    if training.failed:
        verdicts.append(f"{training.failed} of the posterior's design and held-out simulations failed: left out of "
                        "the surrogate's training and of its held-out error")
    return Posterior(chains, surrogate, held, low, high, inflation, len(training.runs), training.designed, widening,
                     training.from_fit, training.failed, band, first, verdicts, training.seconds)
