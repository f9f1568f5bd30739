"""Run the bundled paper scenes at paper size, draw them and measure the paper's statements on them.

    python scripts/gallery.py                       # every scene of paper section 4 (~10 min on 2 cores)
    python scripts/gallery.py maze grate            # some of them
    python scripts/gallery.py directional-h0.5      # the directional scene on 1/2 µm cells (docs/accuracy.md)

Each scene runs exactly as a user would run it, one after another (so each
run time is its own): `biostudy run studies/NAME.toml -o docs/gallery/NAME.nc`,
then `biostudy plot docs/gallery/NAME.nc -o docs/gallery/NAME.png --warp 500`.
The datasets are deleted afterwards (they are large and reproducible); the
table `docs/gallery/runs.md` records each run's wall time, steps, bisections
and where the time went, read from the dataset's attributes, and
`docs/gallery/findings.md` the paper's statements measured on it
(`scripts/findings.py`), which docs/paper.md sets beside the paper.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import xarray as xr

os.environ.setdefault("FIPY_SOLVERS", "scipy")
sys.path.insert(0, str(Path(__file__).resolve().parent))
from findings import FINDINGS  # noqa: E402

from solver.output import on_output_times  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "gallery"
SCENES = ["directional", "agar-g1e8", "agar-g1e10", "obstacles", "maze", "grate"]
# the check docs/paper.md recommends, run like the others but not drawn: a bundled scene on cells of half the size
# (twice the steps); its row is the scene's name with the cell size (docs/accuracy.md compares the two)
REFINED = {"directional-h0.5": ("directional", ["grid.shape=[40,40,40]", "grid.spacing=0.5", "time.steps=2000"])}
ORDER = ["directional", "directional-h0.5", *SCENES[1:]]


def biostudy(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "biostudy", *args], check=True, cwd=ROOT)


def kept_rows(table: Path) -> dict[str, str]:
    """The rows of a markdown table (first column = scene) from an earlier call: scenes not rerun keep theirs."""
    rows = {}
    if table.exists():
        for line in table.read_text().splitlines()[2:]:
            if line.startswith("| "):
                rows.setdefault(line.split("|")[1].strip(), []).append(line)
    return {name: "\n".join(lines) for name, lines in rows.items()}


def main(names: list[str]) -> None:
    from biostudy.inputs.scene import load_scene

    OUT.mkdir(parents=True, exist_ok=True)
    table, findings = OUT / "runs.md", OUT / "findings.md"
    rows, found = kept_rows(table), kept_rows(findings)
    for name in names:
        data = OUT / f"{name}.nc"
        scene, overrides = REFINED.get(name, (name, []))
        biostudy("run", f"studies/{scene}.toml", "-o", str(data), "-q", *(f"--set={o}" for o in overrides))
        if name in REFINED:
            with xr.open_dataset(data) as ds:
                rows[name] = row(name, ds, None)
            data.unlink()
            print(rows[name], flush=True)
            write_tables(table, rows, findings, found)
            continue
        for earlier in OUT.glob(f"{name}_*.png"):  # drawn again; those of a version before biostudy's mark would
            earlier.unlink()                        # not be replaced (docs/reliability.md)
        began = time.perf_counter()
        biostudy("plot", str(data), "-o", str(OUT / f"{name}.png"), "--warp", "500")
        drawn = time.perf_counter() - began
        with xr.open_dataset(data) as ds:
            measured = FINDINGS[name](on_output_times(ds), load_scene(ROOT / "studies" / f"{name}.toml"))
            found[name] = "\n".join(f"| {name} | {statement} | {quantity} | {value} |"
                                     for statement, quantity, value in measured)
            rows[name] = row(name, ds, drawn)
        data.unlink()
        print(rows[name], flush=True)
        write_tables(table, rows, findings, found)  # after every scene: a later failure keeps what was measured


def row(name: str, ds: xr.Dataset, drawn: float | None) -> str:
    """A run's row of runs.md: its size, steps and where its wall time went, from the dataset's attributes."""
    a = ds.attrs
    cells = "×".join(str(ds.sizes[d]) for d in ("x", "y", "z") if d in ds.sizes)
    plot = "–" if drawn is None else f"{drawn:.1f}"
    return (f"| {name} | {cells} | {a['steps_taken']} | {a['steps_bisected']} | {a['mechanics']} | "
            f"{a['wall_time']:.1f} | {a.get('wall_time_mechanics', 0.0):.1f} | {plot} |")


def write_tables(table: Path, rows: dict[str, str], findings: Path, found: dict[str, str]) -> None:
    header = ("| scene | cells | steps | bisected | mechanics | run s | of which mechanics s | plot s |\n"
              "|---|---|---|---|---|---|---|---|")
    ordered = [rows[n] for n in ORDER if n in rows] + [r for n, r in rows.items() if n not in ORDER]
    table.write_text(header + "\n" + "\n".join(ordered) + "\n")
    ordered = [found[n] for n in SCENES if n in found]
    head = "| scene | the paper says | measured | value |\n|---|---|---|---|\n"
    findings.write_text(head + "\n".join(ordered) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:] or ORDER)
