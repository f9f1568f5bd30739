"""What a run counts, declared once: each counter's name and meaning.

Each part of a run (the clock, the nutrient's solver, the biofilm's, the
projections onto the bounds) reports its own counters (`counters()` ->
{name: value}), so the run's cost report collects them without reaching into
the parts' insides; the dataset writes the values as attributes, and what a
counter means is read here (`MEANINGS`) by whoever tabulates them.
"""
from __future__ import annotations

MEANINGS = {
    "steps_taken": "accepted time steps",
    "steps_bisected": "failed steps, bisected",
    "steps_rejected": "steps rejected by the error control",
    "steps_substepped": "steps shortened to the scheme's limit: the growth front crosses at most one cell (Courant "
                        "number <= 1), the expansion source grows at most e-fold (k_alpha dt <= 1)",
    "courant_max": "largest Courant number of a step taken: cells the growth front crossed in one step",
    "largest_step_error": "largest accepted local error estimate in phi (error-controlled steps)",
    "nutrient_cg_iterations": "CG iterations of the nutrient solves, all together",
    "nutrient_amg_rebuilds": "builds of the nutrient's AMG hierarchy",
    "nutrient_active_set_iterations": "active-set iterations of zero-order consumption",
    "biofilm_iterations": "BiCGSTAB iterations of the phi solves, all together",
    "projected_c_count": "values of c the solver projected onto their bounds (round-off)",
    "projected_c_largest": "largest correction of c by that projection",
    "projected_phi_count": "values of phi the solver projected onto their bounds (round-off)",
    "projected_phi_largest": "largest correction of phi by that projection",
    "numerical_diffusion_max": "largest numerical diffusivity |v| h / 2 of upwinding (µm² per T*)",
    "cpu_time_loop": "CPU seconds (the run's threads) of the time loop's steps and mechanics solves, the first of "
                     "each apart",
    "cpu_time_first": "CPU seconds of the first step and first mechanics solve (compiled kernels loaded, first "
                      "hierarchies built: one-off)",
    "cpu_time_setup": "CPU seconds (the run's threads) of the run's set-up: its operators built (Laplacian, face "
                      "tables, mechanics mesh) and the initial nutrient solved",
    "next_step": "the clock's step after the last output: where a continuation of the run goes on",
    "step_limit": "the longest step the scheme's limit allowed by the end (T*; 0: none was needed): a continuation "
                  "keeps to it",
    "threads": "threads the run's kernels and linear solvers' products ran on (the results are the same for any)",
}
# How the counters of a run and of its continuation add up to the whole history's (`solver.restart`): the
# largest of both, the continuation's own, or (every other counter) the sum.
LARGEST = frozenset({"largest_step_error", "courant_max", "projected_c_largest", "projected_phi_largest",
                     "numerical_diffusion_max"})
LAST = frozenset({"next_step", "step_limit", "threads"})

Counters = dict[str, int | float]


def declared(counters: Counters) -> Counters:
    """`counters` as they are, once each name is known to `MEANINGS` (a counter nobody can read is a bug)."""
    unknown = sorted(set(counters) - set(MEANINGS))
    if unknown:
        raise KeyError(f"counters without a meaning in solver.counters.MEANINGS: {', '.join(unknown)}")
    return counters
