"""Verdicts and tables (convergence, stability, sensitivity, show, needs)."""
