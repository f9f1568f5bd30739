"""Measured numbers live in one generated table each; README.md and the guides include them, never copy them.

    python scripts/docs_sync.py           # rewrite the generated blocks of README.md and docs/*.md from the tables
    python scripts/docs_sync.py --check   # exit 1 and name each block that disagrees (tests/test_docs.py)

A generated block in README.md or a guide (`PAGES`) is marked

    <!-- generated: NAME -->
    ...
    <!-- end: NAME -->

and its text comes from `BLOCKS[NAME]()`, which reads a table that a measuring
script wrote: `docs/gallery/runs.md` and `docs/gallery/findings.md`
(`scripts/gallery.py`: the bundled scenes at paper size, and the paper's
section-4 statements measured on them with their verdicts, `scripts/findings.py`),
`docs/measured/agar-tension.txt` (`benchmarks/agar_tension.py`: where the colony
on agar is in tension), `docs/measured/model-laws.txt` (`benchmarks/model_laws.py`:
the bundled scenes under each form of the model's laws),
`docs/measured/suite.md` (`scripts/suite_time.py`: the test suite on this machine),
docs/accuracy.md's convergence summaries and benchmark tables
(`scripts/accuracy_tables.py`: each with the command that made it, which must be
the one that script lists), and `docs/accuracy/stability.md` (`biostudy stability
stability`: the catalogue of stiff and extreme cases, its table as written, which
must hold every case of studies/stability.toml).
"""
from __future__ import annotations

import functools
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from accuracy_tables import MEASURED, MEASURED_OUT, OUT, TABLES  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = (README, *(ROOT / "docs" / f"{page}.md" for page in ("gallery", "paper", "model", "accuracy")))  # with blocks
RUNS = ROOT / "docs" / "gallery" / "runs.md"
FINDINGS = ROOT / "docs" / "gallery" / "findings.md"
TENSION = ROOT / "docs" / "measured" / "agar-tension.txt"
LAWS = ROOT / "docs" / "measured" / "model-laws.txt"
SUITE = ROOT / "docs" / "measured" / "suite.md"
STABILITY = ROOT / "docs" / "accuracy" / "stability.md"
CATALOGUE = ROOT / "studies" / "stability.toml"
TELLING = ("d=1 g=1e10", "g=1e10 zero-order", "r=1e4", "one step to T*=5", "k_alpha=1", "k_alpha=1e3", "large grid",
           "mechanics k_alpha=1", "mechanics alpha=0.2 40^3")  # the rows docs/accuracy.md shows
BLOCK = re.compile(r"(<!-- generated: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- end: (?P=name) -->)", re.S)


def table_rows(path: Path) -> dict[str, dict[str, str]]:
    """A markdown table as {first column: {header: cell}}."""
    lines = [line for line in path.read_text(encoding="utf-8").splitlines() if line.startswith("|")]
    header = [cell.strip() for cell in lines[0].strip("|").split("|")]
    rows = {}
    for line in lines[2:]:
        cells = [cell.strip() for cell in line.strip("|").split("|")]
        rows[cells[0]] = dict(zip(header, cells))
    return rows


def gallery_runs() -> str:
    return RUNS.read_text(encoding="utf-8")


def paper_findings() -> str:
    return FINDINGS.read_text(encoding="utf-8")


def table_lines(path: Path) -> str:
    """The lines of a measuring script's output that are a markdown table."""
    return "".join(line + "\n" for line in path.read_text(encoding="utf-8").splitlines() if line.startswith("|"))


def setup_time() -> str:
    row = table_rows(RUNS)["directional"]
    return (f"the paper's directional-growth scene ({row['run s']} s on 2 cores, of which the mechanics "
            f"{row['of which mechanics s']} s: `docs/gallery/runs.md`):\n")


def suite_time() -> str:
    facts = dict(line.split(": ", 1) for line in SUITE.read_text(encoding="utf-8").splitlines()
                 if ": " in line and not line.startswith(("|", "#")))
    return (f"Run the tests ({facts['tests']} tests in {facts['wall time']} on 2 cores, load average "
            f"{facts['load average']}: `docs/measured/suite.md`; `-m \"not slow\"` leaves out the longest checks):\n")


def stability_summary() -> str:
    """How many cases the catalogue has and what became of them, from its table (which must hold every case)."""
    import tomllib

    rows = table_rows(STABILITY)
    cases = [case["name"] for case in tomllib.loads(CATALOGUE.read_text(encoding="utf-8"))["case"]]
    if sorted(rows) != sorted(cases):
        raise SystemExit(f"{STABILITY.relative_to(ROOT)} is not the table of {CATALOGUE.relative_to(ROOT)}: run "
                         "biostudy stability stability again and copy its stability.md there")
    verdicts = [row["verdict"] for row in rows.values()]
    said = ", ".join(f"{verdicts.count(v)} {words}" for v, words in (
        ("completed", "completed with their bounds held"), ("refused", "refused by the mechanics with its diagnosis"),
        ("stopped", "stopped by a runaway with its diagnosis"), ("failed", "failed")) if verdicts.count(v))
    return (f"`biostudy stability stability -o stab --workers 2`: {len(cases)} cases of `studies/stability.toml` on "
            f"12³ cells of the directional scene, T* = 0.2 in 40 steps, upwind, no mechanics, unless the case says "
            f"otherwise. Result on this machine: **{said}**. "
            f"Full table: `accuracy/stability.md`; the most telling rows:\n")


def stability_rows() -> str:
    rows = table_rows(STABILITY)
    head = ["case", "what it stresses", "verdict", "steps", "bisected", "substepped", "Courant max", "wall s",
            "phi range", "c range"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(rows[name][column] for column in head) + " |" for name in TELLING if name in rows]
    return "\n".join(lines) + "\n"


def made_by(path: Path, command: str) -> str:
    """A table written with its command on the first line, as the command (a sh block) and the table; a table
    made by another command than the listed one is stale."""
    first, _, rest = path.read_text(encoding="utf-8").partition("\n")
    if first != f"command: {command}":
        raise SystemExit(f"{path.relative_to(ROOT)} was made by another command than `{command}`: run python "
                         f"scripts/accuracy_tables.py {path.name.split('.')[0]}")
    return f"```sh\n{command}\n```\n\n{rest.lstrip()}"


BLOCKS = {"gallery-runs": gallery_runs, "paper-findings": paper_findings, "agar-tension": lambda: table_lines(TENSION),
          "model-laws": lambda: table_lines(LAWS), "setup-time": setup_time, "suite-time": suite_time,
          "stability-summary": stability_summary, "stability-rows": stability_rows,
          **{f"accuracy-{name}": functools.partial(made_by, OUT / f"{name}.summary.md", command)
             for name, (command, _) in TABLES.items()},
          **{f"measured-{name}": functools.partial(made_by, MEASURED_OUT / f"{name}.txt", command)
             for name, command in MEASURED.items()}}


def synced(text: str) -> tuple[str, list[str]]:
    """`text` with every generated block rewritten, and the names of the blocks that changed."""
    changed = []

    def rewrite(match: re.Match) -> str:
        name = match["name"]
        if name not in BLOCKS:
            raise SystemExit(f"unknown generated block {name!r} (scripts/docs_sync.py BLOCKS)")
        body = BLOCKS[name]()
        if body != match["body"]:
            changed.append(name)
        return match.group(1) + body + match.group(4)

    return BLOCK.sub(rewrite, text), changed


def main(argv: list[str]) -> int:
    texts = {page: page.read_text(encoding="utf-8") for page in PAGES}
    found = {m["name"] for text in texts.values() for m in BLOCK.finditer(text)}
    missing = sorted(set(BLOCKS) - found)
    stale = False
    for page, text in texts.items():
        new, changed = synced(text)
        stale |= bool(changed)
        name = page.relative_to(ROOT)
        if "--check" in argv:
            for block in changed:
                print(f"{name}: block {block} disagrees with its table; run python scripts/docs_sync.py")
        elif changed:
            page.write_text(new, encoding="utf-8")
            print(f"{name}: rewrote {', '.join(changed)}")
    for block in missing:
        print(f"no page holds the block {block}")
    return 1 if "--check" in argv and (stale or missing) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
