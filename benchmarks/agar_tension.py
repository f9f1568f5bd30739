"""Where the colony on agar (paper 4.2, Fig. 8a) is in tension early on, and why it differs from the paper.

    python benchmarks/agar_tension.py            # four runs of agar-g1e8 to T* = 0.2 (~1 min), a table and a figure

The paper (Fig. 8a, "at the very start of the simulation"): "tension can be seen in the regions where the biofilm
first grows toward the bottom of the discretized domain and toward the nutrients at the top of the biofilm.  Inside
the biofilm, there is pressure".  Its p is the Lagrange multiplier of det Fe = 1 "interpreted as hydrostatic
stress", red tension and blue compression; biostudy's p is the hydrostatic Cauchy stress tr(sigma)/3, negative in
compression — the same sign (4.1 and 4.5 of the paper read the same way: pressure inside, tension at the edge).
Two differences are left, each a run here, all else as bundled (g = 1e8, mechanics solved at T* = 0.2):

* the placement: the paper's disc lies "in the plane directly above" the bottom nodes, so its first growth is down
  into the layer below it; the bundled colony sits on the agar face itself (z = 0 ... 4 µm), here also one cell up
  (z = 1 ... 5 µm);
* the bottom's support: clamped (bundled) or sliding (the paper does not state it for 4.2).

Printed per run: mean p (Pa) in the colony's (phi >= 0.5) bottom 2 µm and top 2 µm, where its largest tension and
compression are, and how much of its tension lies in its lower half.  The figure `docs/gallery/agar_tension.png`
shows p on the vertical cut through the colony's axis (x = 10 µm) for each run, with the phi = 0.5 outline.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

os.environ.setdefault("FIPY_SOLVERS", "scipy")
ROOT = Path(__file__).resolve().parents[1]
BASE = ["time.t_end=0.2", "time.steps=200", "time.outputs=5"]
RUNS = {  # label: overrides of studies/agar-g1e8.toml
    "on the agar, clamped (bundled)": [],
    "on the agar, sliding": ["mechanics.clamp=[]", "mechanics.slide=['z-']"],
    "one cell above, clamped (the paper's plane)": ["biofilm.0.center=[10.0, 10.0, 3.0]"],
    "one cell above, sliding": ["biofilm.0.center=[10.0, 10.0, 3.0]", "mechanics.clamp=[]",
                                "mechanics.slide=['z-']"],
}


def measured(ds) -> tuple[list[str], np.ndarray, np.ndarray]:
    i = ds.sizes["time_mechanics"] - 1
    p, phi = ds["p"].isel(time_mechanics=i).values, ds["phi"].sel(time=ds["time_mechanics"][i]).values
    z = ds.z.values[:, None, None] * np.ones_like(phi)
    colony = phi >= 0.5
    top = z[colony].max()
    base, cap = colony & (z < z[colony].min() + 2), colony & (z > top - 2)
    lower = colony & (z < 0.5 * (z[colony].min() + top))
    tension = np.where(colony, np.maximum(p, 0), 0)
    cells = [f"{np.mean(p[base]):.2g}", f"{np.mean(p[cap]):.2g}", f"{z[colony][np.argmax(p[colony])]:g}",
             f"{z[colony][np.argmin(p[colony])]:g}", f"{tension[lower].sum() / max(tension.sum(), 1e-300):.0%}"]
    return cells, p, phi


def main() -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    from biostudy.inputs import bundled
    from biostudy.inputs.scene import load_scene
    from solver import simulate

    print(f"load average before: {open('/proc/loadavg').read().split()[:3]}")
    head = ["colony", "mean p bottom 2 µm (Pa)", "mean p top 2 µm (Pa)", "largest tension at z (µm)",
            "largest compression at z (µm)", "tension in the lower half"]
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head))
    cuts = []
    for label, overrides in RUNS.items():
        ds = simulate(load_scene(bundled.resolve("agar-g1e8"), BASE + overrides).problem())
        cells, p, phi = measured(ds)
        print("| " + " | ".join([label, *cells]) + " |", flush=True)
        cuts.append((label, p[:, :, 10], phi[:, :, 10]))  # the plane x = 10.5 µm through the axis (z, y)
    low, high = min(np.nanmin(p) for _, p, _ in cuts), max(np.nanmax(p) for _, p, _ in cuts)
    norm = TwoSlopeNorm(vmin=low, vcenter=0.0, vmax=high)  # each side its own scale: the tension is ~10 times weaker
    fig, axes = plt.subplots(1, len(cuts), figsize=(4 * len(cuts), 4), layout="constrained")
    for ax, (label, p, phi) in zip(axes, cuts):
        image = ax.imshow(p, origin="lower", extent=(0, 20, 0, 20), cmap="RdBu_r", norm=norm)
        ax.contour(np.arange(20) + 0.5, np.arange(20) + 0.5, phi, levels=[0.5], colors="k", linewidths=1)
        ax.set_title(label, fontsize=8)
        ax.set_xlabel("y (µm)")
    axes[0].set_ylabel("z (µm); the agar at z = 0")
    fig.colorbar(image, ax=axes, label="p (Pa): blue compression, red tension (scales differ)", shrink=0.8)
    fig.suptitle("agar g = 1e8 at T* = 0.2: p on the cut x = 10.5 µm through the colony (paper Fig. 8a)")
    out = ROOT / "docs" / "gallery" / "agar_tension.png"
    fig.savefig(out, dpi=90)
    print(f"wrote {out.relative_to(ROOT)}")
    print(f"load average after: {open('/proc/loadavg').read().split()[:3]}")


if __name__ == "__main__":
    sys.exit(main())
