"""Stage 5, quantities: what is measured on a run's fields (observables, dense volumes, fronts, norms, the substratum's COMSTAT quantities)."""
