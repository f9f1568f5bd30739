"""Richardson's arithmetic: a quantity's discretisation error from runs at two or more resolutions.

The error model (docs/accuracy.md, "The error model"): a quantity computed on
cells of size h with time steps of mean size dt is

    Q(h, dt) = Q* + a h^p + b dt^q + (higher order),

space and time adding up.  The orders: backward Euler in time, q = 1
(`TIME_ORDER`; docs/accuracy.md measures 0.98); in space the scheme's formal
order (`FORMAL`: upwind 1, TVD 2; the front scene measures 1.4 and 1.8 in the
front position) unless a third grid observes the order: an observed order is
believed between `LOWEST` and the formal order (above it: pre-asymptotic luck,
capped; below `LOWEST`: the runs are not in the asymptotic range, and the
formal order stands).  As in Roache's grid convergence index with an observed
or formal order and no safety factor: an estimate, not a bound.

Every function works elementwise on arrays (one value per output time), with
the ratios of the runs' sizes as numbers; NaN propagates.
"""
from __future__ import annotations

import numpy as np

TIME_ORDER = 1.0  # backward Euler
FORMAL = {"upwind": 1.0, "tvd": 2.0}  # the spatial schemes' orders on smooth data: the most an observation may claim
LOWEST = 0.5  # an observed order below this is not believed (pre-asymptotic): the assumed order stands


def believed(observed: float, formal: float) -> tuple[float, bool]:
    """(order used, observed?): the observed order, capped at the formal order, if it is at least `LOWEST`;
    the formal order otherwise (NaN or smaller observations)."""
    if np.isfinite(observed) and observed >= LOWEST:
        return float(min(observed, formal)), True
    return float(formal), False


def time_part(first: np.ndarray, second: np.ndarray, ratio_first: float, ratio_second: float,
              order: float = TIME_ORDER) -> np.ndarray:
    """b dt^q of the run (step dt) from two runs on one grid with steps ratio_first dt and ratio_second dt:
    their difference is b dt^q (ratio_second^q - ratio_first^q)."""
    return (np.asarray(second, float) - np.asarray(first, float)) / (ratio_second**order - ratio_first**order)


def space_difference(run: np.ndarray, coarse: np.ndarray, time: np.ndarray, ratio_time: float,
                     time_order: float = TIME_ORDER) -> np.ndarray:
    """a h^p (r^p - 1) of the run (h, dt) from a companion at (r h, ratio_time dt) and the run's time part
    b dt^q (`time_part`): the companion's difference less its extra time error."""
    extra_time = np.asarray(time, float) * (ratio_time**time_order - 1.0)
    return np.asarray(coarse, float) - np.asarray(run, float) - extra_time


def space_order(difference: np.ndarray, coarser: np.ndarray, coarse: np.ndarray, refine: float = 2.0,
                extra_time: np.ndarray | float = 0.0) -> float:
    """The spatial order observed from three grids: `coarser` at r^2 h and `coarse` at r h differ by
    a h^p r^p (r^p - 1) (after `extra_time`, the time error `coarser`'s longer step adds), r^p times the
    `difference` a h^p (r^p - 1) between r h and h (`space_difference`).  Pooled over the output times (sums of
    magnitudes: one order per quantity); NaN where nothing differs."""
    upper = np.abs(np.asarray(coarser, float) - np.asarray(coarse, float) - extra_time)
    lower = np.abs(np.asarray(difference, float))
    ok = np.isfinite(upper) & np.isfinite(lower)
    if not ok.any() or lower[ok].sum() <= 0 or upper[ok].sum() <= 0:
        return float("nan")
    return float(np.log(upper[ok].sum() / lower[ok].sum()) / np.log(refine))


def richardson(fine: np.ndarray, coarse: np.ndarray, ratio: float, order: float) -> tuple[np.ndarray, np.ndarray]:
    """(extrapolated value, estimated error of `fine`) from runs at sizes s (fine) and ratio s (coarse) of a
    quantity converging at `order`: Q* = fine + (fine - coarse) / (ratio^order - 1)."""
    correction = (np.asarray(fine, float) - np.asarray(coarse, float)) / (ratio**order - 1.0)
    return np.asarray(fine, float) + correction, np.abs(correction)


def order_of_differences(sizes: np.ndarray, differences: np.ndarray) -> np.ndarray:
    """The order at each output time from the differences of successive levels, (level - 1, time), and the size
    of the coarser level of each difference: the slope of log difference against log size (least squares);
    NaN where fewer than two differences are usable (0 differences, round-off, are not)."""
    sizes = np.asarray(sizes, float)
    differences = np.asarray(differences, float)
    out = np.full(differences.shape[1:], np.nan)
    for t in np.ndindex(out.shape):
        d = differences[(slice(None), *t)]
        ok = np.isfinite(d) & (d > 0) & (sizes > 0)
        if ok.sum() >= 2:
            out[t] = np.polyfit(np.log(sizes[ok]), np.log(d[ok]), 1)[0]
    return out
