"""A height that equals the top of the box is saturated: the biofilm reaches the lid, the value is a lower bound.

`observables` gives every height (``height``, ``height_x``, ...) the domain's
top along its axis as the attribute ``domain_top``; `saturated` says where a
value reaches it.  `show` marks such values, the sweep pictures draw them with
their own marker.  Numpy only: `show` of a run's file uses it without the rest.
"""
from __future__ import annotations

import numpy as np

SATURATION = "domain_top"  # attribute of a height: the top of the box along its axis (µm)


def saturated(values, top: float | None, spacing: float = 1.0) -> np.ndarray:
    """Where `values` reach the domain's `top` (to round-off): False everywhere when there is no top."""
    values = np.asarray(values, dtype=float)
    if top is None or not np.isfinite(float(top)):
        return np.zeros(values.shape, bool)
    top = float(top)
    return np.isfinite(values) & (values >= top - 1e-9 * max(spacing, abs(top)))
