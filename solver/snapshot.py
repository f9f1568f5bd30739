"""One output of a run: its fields and the run's counters then, what the time loop yields and a sink takes."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Snapshot:
    """Fields at one output time, as grid arrays (NaN in obstacles), with the run's counters so far."""

    time: float
    phi: np.ndarray
    c: np.ndarray
    alpha: np.ndarray
    steps: int
    bisections: int
    rejected: int
    elapsed: float
    u: np.ndarray | None = None
    p: np.ndarray | None = None
    mechanics: dict = field(default_factory=dict)
