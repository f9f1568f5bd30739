"""Stage 6, reports: verdicts and tables (convergence, stability, sensitivity, show, needs)."""
