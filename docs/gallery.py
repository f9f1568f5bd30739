"""Run the bundled paper scenes at paper size and draw them: docs/gallery/*.png and the table of run times.

    python docs/gallery.py                       # every scene of paper section 4 (~10 min on 2 cores)
    python docs/gallery.py maze grate            # some of them

Each scene runs exactly as a user would run it, one after another (so each
run time is its own): `biostudy run studies/NAME.toml -o docs/gallery/NAME.nc`,
then `biostudy plot docs/gallery/NAME.nc -o docs/gallery/NAME.png`.  The
datasets are deleted afterwards (they are large and reproducible); the table
`docs/gallery/runs.md` records each run's wall time, steps, bisections and
where the time went, read from the dataset's attributes.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import xarray as xr

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "gallery"
SCENES = ["directional", "agar-g1e8", "agar-g1e10", "obstacles", "maze", "grate"]


def biostudy(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "biostudy", *args], check=True, cwd=ROOT)


def main(names: list[str]) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    rows = {}
    table = OUT / "runs.md"
    if table.exists():  # keep the rows of scenes not rerun this time
        for line in table.read_text().splitlines()[2:]:
            if line.startswith("| "):
                rows[line.split("|")[1].strip()] = line
    for name in names:
        data = OUT / f"{name}.nc"
        biostudy("run", f"studies/{name}.toml", "-o", str(data), "-q")
        began = time.perf_counter()
        biostudy("plot", str(data), "-o", str(OUT / f"{name}.png"))
        drawn = time.perf_counter() - began
        with xr.open_dataset(data) as ds:
            a = ds.attrs
            cells = "×".join(str(ds.sizes[d]) for d in ("x", "y", "z") if d in ds.sizes)
            rows[name] = (f"| {name} | {cells} | {a['steps_taken']} | {a['steps_bisected']} | {a['mechanics']} | "
                          f"{a['wall_time']:.1f} | {a.get('wall_time_mechanics', 0.0):.1f} | {drawn:.1f} |")
        data.unlink()
        print(rows[name], flush=True)
    header = ("| scene | cells | steps | bisected | mechanics | run s | of which mechanics s | plot s |\n"
              "|---|---|---|---|---|---|---|---|")
    ordered = [rows[n] for n in SCENES if n in rows] + [r for n, r in rows.items() if n not in SCENES]
    table.write_text(header + "\n" + "\n".join(ordered) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:] or SCENES)
