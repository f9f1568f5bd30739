"""Is the nutrient quasi-steady at the run's time step?  The model assumes it, and a run must say when it is not.

The model solves the nutrient's steady problem at every step (Eq. 35 with time homogenisation, eta_c << eta_phi:
docs/model.md): it takes the nutrient to settle at once to every new biofilm.  Diffusion settles it across the
domain at the rate of its slowest mode, pi^2 d / (4 L^2) for a source on one side and zero flux at the far one
(consumption only makes it faster inside the biofilm; in the void there is none).  The biofilm changes step by
step, so the nutrient is quasi-steady when that mode decays within a step: warned when after one step of dt more
than 1 % of it is left, exp(-pi^2 d dt / (4 L^2)) > 1 %, i.e. the diffusion time across the domain L^2/d exceeds
pi^2 / (4 ln 100) dt = 0.54 dt.  L is the domain's longest side and dt the nominal step t_end / steps: with Table
2's d = 1e10 µm²/T* across the 20 µm directional cube, L^2/d = 4e-8 T* against dt = 1e-3 T*; with d = 1e-6 it is
4e8 T*.  A warning then says both numbers (`ATTRIBUTE`).  A run with the transient nutrient (`[model] nutrient =
"transient"`, attribute ``nutrient_dynamics``) solves c's own time derivative and assumes nothing of the kind.
"""
from __future__ import annotations

import numpy as np
import xarray as xr

ATTRIBUTE = "nutrient_not_quasi_steady"
LEFT = 0.01  # the share of the slowest diffusion mode left after one step that is still "settled"
FACTOR = np.pi**2 / (4 * np.log(1 / LEFT))  # L^2/d above FACTOR * dt leaves more than LEFT: 0.536


def unsettled(ds: xr.Dataset) -> str:
    """'' if diffusion settles the nutrient across the domain within a step, else the numbers and what to do."""
    attrs = ds.attrs
    needs = ("d", "grid_shape", "grid_spacing", "t_end", "steps_nominal")
    if attrs.get("nutrient_dynamics") == "transient" or not all(name in attrs for name in needs):
        return ""
    side = float(np.max(attrs["grid_shape"])) * float(attrs["grid_spacing"])
    d, dt = float(attrs["d"]), float(attrs["t_end"]) / float(attrs["steps_nominal"])
    diffusion = side**2 / d
    if diffusion <= FACTOR * dt:
        return ""
    return (f"the nutrient is not quasi-steady at this time step: its diffusion time across the domain L²/d = "
            f"{diffusion:.3g} T* (L = {side:g} µm, d = {d:g} µm²/T*) exceeds {FACTOR:.2f} times the step dt = "
            f"{dt:.3g} T*, so more than {LEFT:.0%} of a change is left unsettled after a step, while the model solves "
            f"c as settled at every step (Eq. 35 with eta_c << eta_phi, docs/model.md): its c is the steady state a "
            f"slower diffusion would not reach; a larger d is the regime the model describes")
