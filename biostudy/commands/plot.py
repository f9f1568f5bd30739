"""`biostudy plot FILE.nc`: the pictures of a run or a sweep (`biostudy.plots`), beside the dataset or at `output`.

Options a dataset cannot take (a field it lacks, a cut of a 2-D run, a real time without t_ref) are
`BadInput` naming the file, before anything is drawn.
"""
from __future__ import annotations

from pathlib import Path

from ..data.reading import open_result
from ..data.real_time import t_star
from ..errors import BadInput


def plot(result: str | Path, *, output: str | Path | None = None, variable: str | None = None,
         time: float | str | None = None, cut: str | None = None, warp: float | None = None) -> list[Path]:
    """Draw the pictures of a run's or a study's dataset (a study's directory: its study.nc) and return the
    files written: OUTPUT (default: the dataset's name as .png), with _series, _cut, ... suffixes when there are
    several (the options: `declared.PLOT`).  `time`: the output nearest this T* (or a real time, '12 h', with the
    scene's t_ref)."""
    from ..plots import plot as draw  # lazily: matplotlib only where a picture is drawn

    path = Path(result)
    source = path / "study.nc" if path.is_dir() else path
    ds = open_result(source, ("run", "study"), "nothing to plot")
    try:
        at = None if time is None else t_star(ds, time)
        return draw(ds, Path(output) if output is not None else source.with_suffix(".png"), variable=variable,
                    time=at, cut=cut, warp=warp)
    except ValueError as error:
        raise BadInput(str(error), source) from None
