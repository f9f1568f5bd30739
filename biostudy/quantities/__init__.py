"""Quantities computed from a run's fields on plain arrays (no datasets, no scenes)."""
