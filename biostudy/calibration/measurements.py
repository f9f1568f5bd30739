"""A measurement table as a lab keeps it: PEtab's measurement-table columns, CSV or TSV (docs/calibrate.md).

::

    observableId    simulationConditionId   time    measurement     noiseParameters
    biomass         agar                    12      3.41            0.17
    max_thickness   agar                    12      8.02            0.40

One row per measurement: `observableId` names an observable of the registry
(`biostudy.quantities.observables`: biomass, mean_thickness, max_thickness, ...),
`time` is in the calibration file's `time_unit`, `measurement` is in the
observable's units (biomass in µm³/µm² = µm), `noiseParameters` is the
measurement's standard deviation σ: a number > 0, or the name of a noise
parameter (PEtab's parameter ids, `NOISE_NAME`: σ estimated, one per name;
`noise`), `simulationConditionId`
names one of the calibration's `[conditions]` (empty or absent without them).
PEtab's optional `datasetId`, `replicateId` and `datapointId` are read and
kept as written (calibration.nc, calibration.md and simulation.tsv carry them;
an id with a tab or control character is refused, as is a quoted cell that runs
over several lines, which csv would join without its line break); its
`preequilibrationConditionId` and `observableParameters` are accepted empty
(a value there is refused: nothing here pre-equilibrates, and the observables
have no parameters); any other column is refused rather than ignored.  The delimiter is whichever of tab,
comma and semicolon splits the header line into column names (ties go to the
file's suffix: a tab for `.tsv` and `.tab`, a comma for `.csv`): European
spreadsheets write `;`, and then often decimal commas, which such a table may
use throughout (a point beside them could be a thousands separator: refused).
Numbers are ASCII digits with a decimal mark and an exponent, as a lab writes
them; Python's `float` would also read `3_4` as 34 and Arabic-Indic or
full-width digits.  Every problem of the table is reported at once, one line
each, naming the file, the line and the column (`BadInput`), up to
`SHOWN_PROBLEMS` lines and a count of the others.  The table is a regular file
of at most `TABLE_BYTES`, UTF-8 or, with its byte-order mark, UTF-16 (Excel's
"Unicode text"; `files.read_text`).
"""
from __future__ import annotations

import csv
import math
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import BadInput
from ..inputs.files import read_text

REQUIRED = ("observableId", "time", "measurement", "noiseParameters")
OPTIONAL = ("simulationConditionId", "datasetId", "replicateId", "datapointId")
EMPTY_ONLY = {"preequilibrationConditionId": "pre-equilibration is not supported (leave the column empty)",
              "observableParameters": "the observables have no parameters (leave the column empty)"}
REFUSED: dict[str, str] = {}  # columns refused whatever they hold
NUMBERS = ("time", "measurement", "noiseParameters")
TABLE_BYTES = 16 << 20  # 16 MiB: ~400,000 rows
SHOWN_PROBLEMS = 20  # lines a refused table prints; the others are counted
_NUMBER = {mark: re.compile(rf"[+-]?([0-9]+\{mark}?[0-9]*|\{mark}[0-9]+)([eE][+-]?[0-9]+)?") for mark in ".,"}
_NOT_FINITE = re.compile(r"[+-]?(inf|infinity|nan)", re.IGNORECASE)
_LINE_BREAK = re.compile(r"\r\n|\r|\n")
NOISE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")  # a noise parameter's name (PEtab's parameter ids)
IDS = ("datasetId", "replicateId", "datapointId")  # PEtab's ids, kept as written
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")  # a tab, a line break, what a table cell cannot show


@dataclass(frozen=True)
class Measurement:
    """One row of the table: `line` is its line in the file (for messages), `time` in the table's own unit;
    `columns`: the PEtab columns its table has, in the table's order (one tuple shared by every row; what
    simulation.tsv repeats)."""

    line: int
    observable: str
    time: float
    value: float
    sigma: float
    condition: str = ""
    dataset: str = ""
    replicate: str = ""
    datapoint: str = ""
    noise: str = ""  # the noise parameter naming σ, which is then estimated (`sigma` NaN)
    columns: tuple[str, ...] = field(default=(), compare=False, repr=False)


def _delimiter(path: Path, header: str) -> str:
    """The separator that splits `header` into the most column names of the table; ties go to the suffix's."""
    suffix = path.suffix.lower()
    preferred = {".tsv": "\t", ".tab": "\t", ".csv": ","}.get(suffix, "\t" if "\t" in header else ",")
    names = set(REQUIRED + OPTIONAL) | set(EMPTY_ONLY) | set(REFUSED)

    def found(separator: str) -> int:
        try:
            return sum(cell.strip() in names for cell in next(csv.reader([header], delimiter=separator)))
        except csv.Error:  # a wide header is one cell beyond csv's field limit when split at the wrong mark
            return -1

    return max((preferred, "\t", ",", ";"), key=found)


@dataclass(frozen=True)
class _Decimals:
    """The decimal mark of a table's numbers: a point, or a comma throughout a `;` table that writes one
    (`first`: where it does first, for messages)."""

    mark: str = "."
    first: str = ""

    def value(self, text: str) -> float | None:
        """The number `text` writes, None if it is no number as a lab writes one."""
        return float(text.replace(",", ".")) if _NUMBER[self.mark].fullmatch(text) else None

    def refusal(self, text: str) -> str:
        if self.mark == "," and _NUMBER["."].fullmatch(text):
            return (f"{text!r} has a point where this table writes decimals with a comma ({self.first}); "
                    "a thousands separator is not read")
        if _NOT_FINITE.fullmatch(text):
            return f"must be a finite number (got {text!r})"
        if self.mark == "." and _NUMBER[","].fullmatch(text):
            return f"not a number (got {text!r}): decimal commas are read in ';'-separated tables only"
        return f"not a number (got {text!r})"


def _decimals(delimiter: str, header: list[str], rows: list[tuple[int, int, list[str]]]) -> _Decimals:
    """A comma in a number of a `;` table makes the comma its decimal mark."""
    if delimiter != ";":
        return _Decimals()
    columns = [(header.index(name), name) for name in NUMBERS if name in header]
    for line, _, cells in rows:
        for index, name in columns:
            if index < len(cells) and "," in cells[index]:
                return _Decimals(",", f"line {line}: {name}")
    return _Decimals()


def _number(text: str, column: str, line: int, path: Path, problems: list[BadInput], decimals: _Decimals,
            positive: bool = False):
    where = f"line {line}: {column}"
    if not text:
        what = ("the standard deviation sigma of the measurement, or a noise parameter's name"
                if column == "noiseParameters" else "a number")
        problems.append(BadInput(f"missing ({what})", path, where))
        return None
    value = decimals.value(text)
    if value is None or not math.isfinite(value):
        refused = decimals.refusal(text) if value is None else f"must be a finite number (got {text!r})"
        if positive and refused.startswith("not a number ("):  # noiseParameters
            refused = (f"neither a number nor a noise parameter's name (got {text!r}; a name is letters, digits "
                       "and _, not starting with a digit)")
        problems.append(BadInput(refused, path, where))
        return None
    if positive and value <= 0:
        problems.append(BadInput(f"the standard deviation must be > 0 (got {text})", path, where))
        return None
    return value


def _named(text: str) -> bool:
    """Whether a noiseParameters cell names a noise parameter (not inf or nan, which are refused numbers)."""
    return bool(NOISE_NAME.fullmatch(text)) and not _NOT_FINITE.fullmatch(text)


def refusal(problems: list[BadInput], path: str | Path) -> BadInput:
    """The problems of a table as one `BadInput`: the first `SHOWN_PROBLEMS`, then a line that counts the others
    (a table of 100,000 bad rows is not 100,000 lines)."""
    shown = problems[:SHOWN_PROBLEMS]
    if len(problems) > SHOWN_PROBLEMS:
        shown.append(BadInput(f"… and {len(problems) - SHOWN_PROBLEMS:,} more problems", path))
    return BadInput(shown[0].problem, shown[0].file, shown[0].key, tuple(shown[1:]))


def read_measurements(path: str | Path) -> list[Measurement]:
    """Every row of a measurement table; `BadInput` with every problem found (missing or refused columns, an
    empty table, non-numbers, non-finite numbers, sigma <= 0 or missing)."""
    path = Path(path)
    text = read_text(path, TABLE_BYTES, "a measurement table", spreadsheet=True)
    lines = _LINE_BREAK.split(text)  # not str.splitlines: an editor's lines, not every break Unicode knows
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        raise BadInput("is empty: a measurement table needs a header line (" + ", ".join(REQUIRED) + ")", path)
    delimiter = _delimiter(path, lines[first])
    reader = csv.reader(lines[first:], delimiter=delimiter)
    read: list[tuple[int, int, list[str]]] = []  # (its first line, its last line, cells) per row
    try:
        for cells in reader:
            read.append((read[-1][1] + 1 if read else first + 1, first + reader.line_num, cells))
    except csv.Error as error:  # a cell beyond csv's field limit (128 KiB)
        raise BadInput(f"cannot be read as a table ({error})", path, f"line {first + reader.line_num}") from None
    header, table = [name.strip() for name in read[0][2]], read[1:]
    missing = [name for name in REQUIRED if name not in header]
    problems = [BadInput(f"missing column {name} (PEtab's measurement table: "
                         f"{', '.join(REQUIRED)}, optionally {', '.join(OPTIONAL)})", path) for name in missing]
    counts = Counter(header)
    for name in counts:
        if name in REFUSED:
            problems.append(BadInput(f"column {name}: {REFUSED[name]}", path))
        elif name not in REQUIRED + OPTIONAL + tuple(EMPTY_ONLY):
            problems.append(BadInput(f"unknown column {name!r} (PEtab's measurement table: {', '.join(REQUIRED)}, "
                                     f"optionally {', '.join(OPTIONAL)})", path))
    problems += [BadInput(f"column {name!r} comes {'twice' if counts[name] == 2 else f'{counts[name]:,} times'}",
                          path) for name in sorted(counts) if counts[name] > 1]
    if problems:
        raise refusal(problems, path)
    decimals = _decimals(delimiter, header, table)
    columns = tuple(header)
    rows = []
    for line, last, cells in table:
        if not any(cell.strip() for cell in cells):
            continue
        if last > line:
            problems.append(BadInput(f"a quoted cell runs on to line {last}: a cell is one line (csv joins its "
                                     "lines without their line break, so the row would not be as written; close "
                                     "the quote on its line)", path, f"line {line}"))
            continue
        if len(cells) != len(header):
            problems.append(BadInput(f"has {len(cells)} cells, the header {len(header)}", path, f"line {line}"))
            continue
        row = {name: cell.strip() for name, cell in zip(header, cells)}
        if not row["observableId"]:
            problems.append(BadInput("missing (the observable's name)", path, f"line {line}: observableId"))
        problems += [BadInput(f"{why} (got {row[name]!r})", path, f"line {line}: {name}")
                     for name, why in EMPTY_ONLY.items() if row.get(name)]
        problems += [BadInput(f"has a tab or control character (got {row[name]!r}): an id is printable text, as "
                              "calibration.md, calibration.nc and simulation.tsv write it", path,
                              f"line {line}: {name}") for name in IDS if _CONTROL.search(row.get(name, ""))]
        time = _number(row["time"], "time", line, path, problems, decimals)
        value = _number(row["measurement"], "measurement", line, path, problems, decimals)
        noise = row["noiseParameters"] if _named(row["noiseParameters"]) else ""
        sigma = math.nan if noise else _number(row["noiseParameters"], "noiseParameters", line, path, problems,
                                               decimals, positive=True)
        if None not in (time, value, sigma) and row["observableId"]:
            rows.append(Measurement(line, row["observableId"], time, value, sigma,
                                    row.get("simulationConditionId", ""), row.get("datasetId", ""),
                                    row.get("replicateId", ""), row.get("datapointId", ""), noise=noise,
                                    columns=columns))
    if not problems and not rows:
        problems.append(BadInput("has a header but no measurements", path))
    if problems:
        raise refusal(problems, path)
    return rows
