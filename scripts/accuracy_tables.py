"""The convergence tables of docs/accuracy.md, each made by the command printed beside it.

    python scripts/accuracy_tables.py                    # every table (~10 min on 2 cores)
    python scripts/accuracy_tables.py front-time grate-reduced
    python scripts/accuracy_tables.py --measured         # also the error-estimate benchmarks (~10 min more)

Each entry of `TABLES` is a `biostudy convergence` command; it runs into a
temporary directory, and its convergence.md and work_precision.png are kept as
docs/accuracy/NAME.md and NAME.png, its summary (one row per series: the errors
of its levels, the observed orders, at the compared time; the reference with
its own error) as docs/accuracy/NAME.summary.md, the command on its first line.
`scripts/docs_sync.py` puts the command and the summary into docs/accuracy.md
(blocks ``accuracy-NAME``) and refuses a summary made by another command than
the one listed here.  `MEASURED` are the benchmarks whose tables docs/accuracy.md
shows the same way (their output in docs/measured/NAME.txt).
"""
from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "accuracy"
MEASURED_OUT = ROOT / "docs" / "measured"

TABLES = {
    "front-smooth-upwind": ("biostudy convergence front --levels 5 --series space --set biofilm.0.edge=2.0 "
                            "--set 'numerics.advection=\"upwind\"' --set time.steps=200",
                            ("phi_L1", "biofilm_volume", "front_position")),
    "front-smooth-tvd": ("biostudy convergence front --levels 5 --series space --set biofilm.0.edge=2.0 "
                         "--set 'numerics.advection=\"tvd\"' --set time.steps=200",
                         ("phi_L1", "biofilm_volume", "front_position")),
    "front-time": ("biostudy convergence front --levels 4 --series time,adaptive --set time.t_end=0.1 "
                   "--set time.steps=20", ("phi_L1", "front_position")),
    "directional-reduced": ("biostudy convergence directional --levels 3 --series space,time,adaptive "
                            "--set grid.shape=[10,10,10] --set grid.spacing=2.0 --set time.t_end=0.5 "
                            "--set time.steps=50 --set mechanics.enabled=false",
                            ("phi_L1", "biofilm_volume", "front_position")),
    "grate-reduced": ("biostudy convergence grate --levels 3 --series space,time,adaptive --set grid.shape=[20,30] "
                      "--set grid.spacing=2.0 --set time.t_end=1.0 --set time.steps=250 --set mechanics.enabled=false",
                      ("phi_L1", "biofilm_volume", "front_position")),
    "agar2d-reduced": ("biostudy convergence agar2d --levels 3 --series space,time --set grid.shape=[20,40] "
                       "--set time.t_end=0.3 --set time.steps=150 --set 'numerics.growth_velocity=\"front\"'",
                       ("phi_L1", "biofilm_volume", "mean_thickness")),
}
MEASURED = {
    "error-estimate": "python benchmarks/error_estimate.py",
    "error-estimate-cost": "python benchmarks/error_estimate_cost.py",
}


def _errors(values) -> str:
    import numpy as np

    return ", ".join(f"{v:.1e}" if np.isfinite(v) else "ref" for v in values) if len(values) else "-"


def summary(ds, quantities: tuple[str, ...]) -> str:
    """One row per series at the compared time: h, dt and cost of each level, the errors, the observed orders."""
    import numpy as np

    times = ds["time"].values
    at = int(np.argmin(np.abs(times - float(ds.attrs.get("compared_time", times[-1])))))
    head = ["series", "h µm", "dt", "cost s", *(f"err {q}" for q in quantities), *(f"order {q}" for q in quantities)]
    lines = [f"Errors at T* = {times[at]:g}, levels coarse to fine, against the reference below.", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in ds.series.values:
        row = ds.sel(series=name)
        finished = np.isfinite(row.cells.values)
        cells = [str(name), ", ".join(f"{h:g}" for h in row.h.values[finished]),
                 ", ".join(f"{d:.2g}" for d in row.dt.values[finished]),
                 ", ".join(f"{c:.2g}" for c in row.cost.values[finished])]
        cells += [_errors(row[f"error_{q}"].isel(time=at).values[finished]) for q in quantities]
        orders = [ds.attrs.get(f"order_{name}_{q}", float("nan")) for q in quantities]
        cells += [o if isinstance(o, str) else (f"{o:.2f}" if np.isfinite(o) else "-") for o in orders]
        different = [int(level) for level in row.level.values if float(row.resolved.sel(level=level)) == 0]
        if different:
            cells[0] += f" (level {', '.join(map(str, different))}: a different model)"
        lines.append("| " + " | ".join(cells) + " |")
    reference = [f"{q} {float(ds[f'reference_{q}'][at]):.4g} ± {float(ds[f'reference_error_{q}'][at]):.2g}"
                 for q in quantities if f"reference_{q}" in ds]
    if reference:
        lines += ["", f"Reference at T* = {times[at]:g} (Richardson from the finest two levels of `both`, ± its own "
                      f"estimated error): {'; '.join(reference)}."]
    return "\n".join(lines) + "\n"


def make(name: str) -> None:
    import xarray as xr

    command, quantities = TABLES[name]
    args = shlex.split(command)[2:]  # after "biostudy convergence"
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "conv"
        subprocess.run([sys.executable, "-m", "biostudy", "convergence", *args, "-o", str(out), "-q"], check=True,
                       cwd=ROOT, env={**os.environ, "FIPY_SOLVERS": "scipy"})
        shutil.copy(out / "convergence.md", OUT / f"{name}.md")
        shutil.copy(out / "work_precision.png", OUT / f"{name}.png")
        with xr.open_dataset(out / "convergence.nc") as ds:
            text = summary(ds.load(), quantities)
    load = os.getloadavg()[0]
    (OUT / f"{name}.summary.md").write_text(f"command: {command}\nload average: {load:.1f}\n\n{text}",
                                            encoding="utf-8")
    print(f"wrote docs/accuracy/{name}.md, .png, .summary.md")


def measure(name: str) -> None:
    args = shlex.split(MEASURED[name])[1:]
    done = subprocess.run([sys.executable, *args], check=True, cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, "FIPY_SOLVERS": "scipy"})
    (MEASURED_OUT / f"{name}.txt").write_text(f"command: {MEASURED[name]}\n{done.stdout}", encoding="utf-8")
    print(f"wrote docs/measured/{name}.txt")


def main(argv: list[str]) -> None:
    names = [a for a in argv if not a.startswith("--")] or list(TABLES)
    for name in names:
        if name in MEASURED:
            measure(name)
        else:
            make(name)
    if "--measured" in argv:
        for name in MEASURED:
            measure(name)


if __name__ == "__main__":
    main(sys.argv[1:])
