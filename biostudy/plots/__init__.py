"""Pictures of a run or a sweep (`biostudy plot`): the figures a scientist looks at first.

`plot(ds, out)` draws, from one call:

- every run: the time series of mean phi and mean c (paper Figs. 4 and 7) and
  the biofilm volume                                            -> OUT_series.png
- a 3-D run: phi, c (and p) on the paper's diagonal cut at four times
  (Tables 3 and 5; `cut` picks another plane)                   -> OUT_cut.png
  and the phi >= 0.8 region in 3-D at four times (Figs. 3, 10)  -> OUT_isosurface.png
- a 2-D run: maps of phi, c (and p) at four times               -> OUT_maps.png
  and, where its route passes dead ends, the biofilm in each
  over time (paper 4.4)                                          -> OUT_dead_ends.png
- a sweep (`study.nc`): final outputs (observables) against the swept
  parameters                                                    -> OUT_sweep.png
  and the time series of every case                             -> OUT_series.png
  (a sampled study: every output against every parameter, scattered)
- with `warp`: the deformed body, displacement magnified (Fig. 13) -> OUT_warped.png

Options narrow it down: `variable` draws one field (or one sweep output),
`time` the output nearest to it, `cut` the plane of a 3-D run.  Bad options
raise ValueError with a one-line message before anything is drawn; so does
a picture to be written over a file biostudy did not write (`BadInput`).
Every figure is drawn before the first is saved, and each is saved
atomically: a failure leaves no picture of this call behind, complete or
partial.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import xarray as xr

from solver.output import on_output_times

from ..data.claims import foreign
from ..quantities import dead_ends as dead_end_geometry
from ..quantities import observables
from . import analysis, dead_ends, fields, isosurface, series, sweep, warped
from .cuts import plane_for
from .style import SERIES_NAMES, field_names, output_paths, save, snapshot_indices

__all__ = ["plot"]


def plot(ds: xr.Dataset, out: Path, variable: str | None = None, time: float | None = None,
         cut: str | None = None, warp: float | None = None) -> list[Path]:
    """Draw the default figures of `ds` (a run or a sweep) and return the files written.

    out: the picture's path; with several figures, `stem_<tag>.png` beside it
        (tags: series, cut, isosurface, maps, dead_ends, sweep).
    variable: one of the dataset's fields (phi, c, alpha, p) or, for a sweep,
        one of phi_mean, c_mean, biofilm_volume.
    time: draw the output nearest to this T* instead of four spread over the run
        (a sweep: its outputs at that time instead of the last).
    cut: 3-D runs only: 'diagonal' (default, toward the nutrient source), 'xy-diagonal',
        or 'x=10', 'y=4.5', 'z=5.5' (µm).
    warp: also draw the deformed body with the displacement magnified by this factor (runs with mechanics).
    """
    ds = on_output_times(ds)  # p and u per output index, NaN where the mechanics was not solved
    if warp is not None and (sweep.is_sweep(ds) or not warp > 0):
        raise ValueError("--warp needs a positive factor and one run's dataset" if sweep.is_sweep(ds)
                         else f"--warp must be a positive factor (got {warp:g})")
    if sweep.is_sweep(ds):
        figures = _sweep_figures(ds, variable, time, cut)
    elif "z" in ds.dims:
        names, indices = field_names(ds, variable), snapshot_indices(ds, time)
        plane = plane_for(ds, cut)
        figures = [("series", lambda: series.figure(ds, _marks(ds, indices, time))),
                   ("cut", lambda: fields.cut_figure(ds, names, indices, plane))]
        if "phi" in names:
            figures.append(("isosurface", lambda: isosurface.figure(ds, indices)))
    else:
        names, indices = field_names(ds, variable), snapshot_indices(ds, time)
        if cut is not None:
            raise ValueError(f"cut {cut!r} needs a 3-D run; this run is 2-D (its maps are the whole domain)")
        figures = [("series", lambda: series.figure(ds, _marks(ds, indices, time))),
                   ("maps", lambda: fields.map_figure(ds, names, indices))]
        if variable is None and dead_end_geometry.applies(ds):
            figures.append(("dead_ends", lambda: dead_ends.figure(ds, indices)))
    if warp is not None:
        shown = warped.solved_indices(ds, indices)  # refuses before anything is drawn
        figures.append(("warped", lambda: warped.figure(ds, shown, warp)))
    paths = output_paths(Path(out), [tag for tag, _ in figures])
    foreign(paths, "a picture")  # before anything is drawn
    drawn = []
    try:
        for _, draw in figures:
            drawn.append(draw())
    except BaseException:
        for fig in drawn:
            plt.close(fig)
        raise
    saved = []
    try:
        for fig, path in zip(drawn, paths):
            saved.append(save(fig, path))
    except BaseException:
        for path in saved:
            path.unlink(missing_ok=True)
        for fig in drawn:
            plt.close(fig)
        raise
    return saved


def _marks(ds: xr.Dataset, indices: list[int], time: float | None) -> list[float]:
    return [float(ds["time"].values[i]) for i in indices] if time is not None else []


def _sweep_figures(ds: xr.Dataset, variable: str | None, time: float | None, cut: str | None):

    known = [n for n in dict.fromkeys((*SERIES_NAMES, *observables.REGISTRY)) if n in ds]
    if variable is not None and variable not in known:
        raise ValueError(f"unknown variable {variable!r} for a sweep; it has {', '.join(known)}")
    if cut is not None:
        raise ValueError("a sweep has no fields to cut; plot one case's file for cuts")
    shown = [n for n in dict.fromkeys((*SERIES_NAMES, *observables.SUMMARY)) if n in ds and ds[n].notnull().any()]
    names = [variable] if variable else shown
    index = -1 if time is None else snapshot_indices(ds, time)[0]
    if "sample_method" in ds.attrs:
        return [("sweep", lambda: analysis.sample_figure(ds, names, index)),
                ("series", lambda: analysis.sample_series_figure(ds, names))]
    return [("sweep", lambda: sweep.final_figure(ds, names, index)),
            ("series", lambda: sweep.series_figure(ds, names))]
