"""One run on several threads with the serial run's results, bit for bit.

`team` (the threads), `rows` (work in blocks of rows: sparse products), `vectors` (the Krylov solvers' fused
updates), `sweeps` (pipelined Gauss-Seidel), `atomic` (what the sweeps' threads wait with), `blas` (the BLAS
libraries' own threads: one).  Every kernel computes each entry of its result with the serial code's operations
in the serial code's order, whichever thread computes it; sums over whole vectors stay serial.  Why threads of
our own and not numba's ``parallel=True``: `team`.  What it gains: docs/transport.md, "Threads".
"""
from .team import SERIAL, Team, cores

__all__ = ["SERIAL", "Team", "cores"]
