"""The two estimators of the COMSTAT observables on a hemisphere (docs/comstat.md).

A hemisphere of radius 4 µm on the z- face, segmented (phi = 1 in the cells whose centres lie inside, else 0),
on cells of h = 1, 1/2, 1/4 µm: surface to biovolume (exact 3/r = 0.75 µm⁻¹) and biomass (exact 2/3 π r³ over
the 12 x 12 µm² substratum) by the sub-cell level set (`quantities.substratum`) and by COMSTAT's voxel counts
(`quantities.comstat`).

    python benchmarks/comstat.py
"""
import numpy as np

from biostudy.quantities import comstat, substratum

RADIUS, SIDE, HEIGHT = 4.0, 12.0, 8.0


def hemisphere(h: float) -> np.ndarray:
    n, nz = int(round(SIDE / h)), int(round(HEIGHT / h))
    across, up = (np.arange(n) + 0.5) * h, (np.arange(nz) + 0.5) * h
    z, y, x = np.meshgrid(up, across, across, indexing="ij")
    return (((x - SIDE / 2) ** 2 + (y - SIDE / 2) ** 2 + z**2) <= RADIUS**2).astype(float)


def main() -> None:
    exact_ratio, exact_biomass = 3 / RADIUS, 2 / 3 * np.pi * RADIUS**3 / SIDE**2
    print("| h (µm) | S/V sub-cell | S/V voxel | S/V exact | biomass sub-cell | biomass voxel | biomass exact |")
    print("|---|---|---|---|---|---|---|")
    for h in (1.0, 0.5, 0.25):
        phi = hemisphere(h)
        voxel = comstat.voxel_observables(phi, h, "z-")
        print(f"| {h:g} | {substratum.surface_to_biovolume(phi, h, 'z-'):.3f} | {voxel['surface_to_biovolume']:.3f} "
              f"| {exact_ratio:.3f} | {substratum.biomass(phi, h, 'z-'):.4f} | {voxel['biomass']:.4f} "
              f"| {exact_biomass:.4f} |")


if __name__ == "__main__":
    main()
