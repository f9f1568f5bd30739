"""Run the bundled paper scenes at paper size, draw them and measure the paper's statements on them.

    python scripts/gallery.py                       # every scene of paper section 4 (~15 min on 2 cores)
    python scripts/gallery.py maze grate            # some of them
    python scripts/gallery.py directional-h0.5      # the directional scene on 1/2 µm cells (docs/accuracy.md)

Each scene runs exactly as a user would run it, one after another (so each
run time is its own): `biostudy run studies/NAME.toml -o docs/gallery/NAME.nc`,
then `biostudy plot docs/gallery/NAME.nc -o docs/gallery/NAME.png` (`--warp 500` with mechanics).
The datasets are deleted afterwards (they are large and reproducible); the
table `docs/gallery/runs.md` records each run's wall time, steps, bisections
and where the time went, read from the dataset's attributes, and
`docs/gallery/findings.md` the paper's statements measured on it, each with its
verdict (`scripts/findings.py`; the numbers statements about several runs need
are kept in `docs/gallery/facts.json`), which `scripts/docs_sync.py` renders
into docs/paper.md.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import xarray as xr

os.environ.setdefault("FIPY_SOLVERS", "scipy")
sys.path.insert(0, str(Path(__file__).resolve().parent))
from findings import ACROSS, FINDINGS  # noqa: E402

from solver.output import on_output_times  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "gallery"
SCENES = ["directional", "agar-g1e8", "agar-g1e10", "obstacles", "maze", "dead-end", "grate"]
# variants run like the others but not drawn: the check docs/paper.md recommends, a bundled scene on cells of half
# the size (twice the steps; docs/accuracy.md compares the two), and 4.1's source three cells wide (its mean c)
REFINED = {"directional-h0.5": ("directional", ["grid.shape=[40,40,40]", "grid.spacing=0.5", "time.steps=2000"]),
           "directional-source3": ("directional", ["nutrient.0.lower=[17.0,17.0,17.0]", "mechanics.enabled=false"])}
ORDER = ["directional", *REFINED, *SCENES[1:]]


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
    table, findings, facts_file = OUT / "runs.md", OUT / "findings.md", OUT / "facts.json"
    rows = kept_rows(table)
    found = kept_rows(findings) if findings.exists() and findings.read_text().startswith("| run | §") else {}
    facts = json.loads(facts_file.read_text()) if facts_file.exists() else {}
    for name in names:
        data = OUT / f"{name}.nc"
        scene, overrides = REFINED.get(name, (name, []))
        sets = [f"--set={o}" for o in overrides]
        load = os.getloadavg()[0]  # beside the run's time: this machine is shared
        biostudy("run", f"studies/{scene}.toml", "-o", str(data), "-q", *sets)
        drawn = None
        if name not in REFINED:
            for earlier in OUT.glob(f"{name}_*.png"):  # drawn again; those of a version before biostudy's mark
                earlier.unlink()                        # would not be replaced (docs/reliability.md)
            began = time.perf_counter()
            with xr.open_dataset(data) as ds:
                warp = ["--warp", "500"] if ds.attrs.get("mechanics") == "on" else []
            biostudy("plot", str(data), "-o", str(OUT / f"{name}.png"), *warp)
            drawn = time.perf_counter() - began
        with xr.open_dataset(data) as ds:
            if name in FINDINGS:
                measured, facts[name] = FINDINGS[name](on_output_times(ds), load_scene(ROOT / "studies" /
                                                                                        f"{scene}.toml", overrides))
                found[name] = "\n".join(table_row(name, f) for f in measured)
            rows[name] = row(name, ds, drawn, load)
        data.unlink()
        for label, (needs, across) in ACROSS.items():
            if name in needs and all(n in facts for n in needs):
                found[label] = "\n".join(table_row(label, f) for f in across(facts))
        print(rows[name], flush=True)
        facts_file.write_text(json.dumps(facts, indent=1, sort_keys=True) + "\n")
        write_tables(table, rows, findings, found)  # after every scene: a later failure keeps what was measured


def table_row(run: str, finding) -> str:
    """A finding as a row of findings.md."""
    tags = [t.strip() for t in finding.pictures.split(",") if t.strip()] if run in SCENES else []
    pictures = ", ".join(f"[{tag.removesuffix('.png')}](gallery/{tag})" if tag.endswith(".png") else
                         f"[{tag}](gallery/{run}_{tag}.png)" for tag in tags)
    cells = (run, finding.section, finding.statement, finding.measured, finding.value, finding.verdict, pictures)
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def row(name: str, ds: xr.Dataset, drawn: float | None, load: float) -> str:
    """A run's row of runs.md: its size, steps and where its wall time went, from the dataset's attributes, and the
    machine's load average (1 min) when it started."""
    a = ds.attrs
    cells = "×".join(str(ds.sizes[d]) for d in ("x", "y", "z") if d in ds.sizes)
    plot = "–" if drawn is None else f"{drawn:.1f}"
    return (f"| {name} | {cells} | {a['steps_taken']} | {a['steps_bisected']} | {a['mechanics']} | "
            f"{a['wall_time']:.1f} | {a.get('wall_time_mechanics', 0.0):.1f} | {plot} | {load:.1f} |")


def write_tables(table: Path, rows: dict[str, str], findings: Path, found: dict[str, str]) -> None:
    header = ("| scene | cells | steps | bisected | mechanics | run s | of which mechanics s | plot s | load |\n"
              "|---|---|---|---|---|---|---|---|---|")
    ordered = [rows[n] for n in ORDER if n in rows] + [r for n, r in rows.items() if n not in ORDER]
    table.write_text(header + "\n" + "\n".join(ordered) + "\n")
    order = [*ORDER, *ACROSS]
    ordered = [found[n] for n in sorted(found, key=lambda n: (_section(found[n]), order.index(n) if n in order
                                                               else len(order)))]
    head = ("| run | § | the paper says | measured | ours | verdict | pictures |\n"
            "|---|---|---|---|---|---|---|\n")
    findings.write_text(head + "\n".join(ordered) + "\n")


def _section(rows: str) -> str:
    """The paper's section of a run's rows (its first row's second cell)."""
    return rows.split("|")[2].strip()


if __name__ == "__main__":
    main(sys.argv[1:] or ORDER)
