"""What is measured on a run's fields.

Observables, dense volumes, fronts, norms, and the substratum's quantities as COMSTAT measures them.
"""
