"""Output for scripts and logs (issue 27, item 5): tables never cut when not on a terminal, `--json`, and
`-q`/`-v` with the `logging` module."""
from __future__ import annotations

import json
import logging
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.data import reading
from biostudy.formatting import number

runner = CliRunner()  # stdout and stderr are not terminals here, as in a pipe or a batch log


def invoke(*args, env=None):
    return runner.invoke(app, [str(a) for a in args], env=env)


def test_tables_to_a_pipe_are_not_cut(write_toml, tmp_path):
    """A table wider than 80 columns keeps every cell whole when stdout is not a terminal (rich cut it to the
    80 columns of a console of unknown width: 'spre…', descriptions wrapped over lines)."""
    description = "a description long enough to make this table far wider than eighty columns, " * 2
    write_toml("wide-scene-with-a-long-name.toml", f'description = "{description.strip()}"\n[grid]\nshape = [4, 4]\n')
    result = invoke("scenes", env={"BIOSTUDY_STUDIES": str(tmp_path), "COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    row = next(line for line in result.stdout.splitlines() if "wide-scene-with-a-long-name.toml" in line)
    assert description.strip() in row and "…" not in result.stdout


def _strict(text: str):
    """json.loads that refuses NaN and infinities (Python's accepts them; JSON has none)."""
    def refuse(constant):
        raise ValueError(f"not JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


def _rows(table: str, first: str) -> dict[str, list[str]]:
    """Rows of a rich table (cells split on its vertical bars) by their first cell."""
    rows = {}
    for line in table.splitlines():
        cells = [c.strip() for c in re.split(r"[│┃]", line)]
        if len(cells) > 2 and cells[0] and cells[0] != first:
            rows[cells[0]] = cells[1:]
    return rows


def test_show_json_of_a_run_has_every_observable_with_the_tables_numbers(tiny_scene, tmp_path):
    out = tmp_path / "run.nc"
    assert invoke("run", tiny_scene, "-o", out, "-q").exit_code == 0
    shown, table = invoke("show", "--json", out), invoke("show", out)
    assert shown.exit_code == 0 and table.exit_code == 0, shown.output + table.output
    record = _strict(shown.stdout)  # stdout is the JSON and nothing else
    ds = reading.open_dataset(out)
    names = [n.strip() for n in ds.attrs["observables"].split(",")]
    assert list(record["observables"]) == names and record["time"] == ds.time.values.tolist()
    rows = _rows(table.stdout, "observable")
    for name in names:
        values = record["observables"][name]["values"]
        assert values == [None if np.isnan(v) else v for v in ds[name].values.tolist()]
        first, last = (number(np.nan if v is None else v) for v in (values[0], values[-1]))
        assert rows[name][:2] == [first, last], name
    assert record["attributes"]["g"] == 1e8 and record["scene"] == "tiny"
    assert _strict(invoke("show", "--json", out, out).stdout) == [record, record]  # several files: a list


def test_sweep_json_is_the_study_with_the_numbers_of_show(tiny_study, tmp_path):
    out = tmp_path / "sweep"
    swept = invoke("sweep", tiny_study, "-o", out, "--json", "-v")
    assert swept.exit_code == 0, swept.output
    record = _strict(swept.stdout)
    ended = {line for line in swept.stderr.splitlines() if line.endswith(" done") and " " not in line[:-5]}
    assert ended == {f"{case['case_id']} done" for case in record["cases"]}  # -v: each case's end, a line each
    assert record["kind"] == "study" and record["swept"] == ["g", "r"] and len(record["cases"]) == 4
    rows = _rows(invoke("show", out).stdout, "case")
    for case in record["cases"]:
        row = rows[case["case_id"]]
        assert row[0] == case["status"] == "done"
        assert row[1:3] == [number(case["wall_time"]), number(case["steps_taken"])]
        observables = [number(case[n]) for n in record["observables_units"]]
        assert row[3:3 + len(observables)] == observables, case["case_id"]
    assert _strict(invoke("show", "--json", out).stdout)["cases"] == record["cases"]
    analysed = invoke("analyze", out, "--output", "biofilm_volume", "--json")
    assert analysed.exit_code == 0, analysed.output
    variables = _strict(analysed.stdout)["variables"]
    table = (out / "analysis.md").read_text()
    for j, parameter in enumerate(["g", "r"]):
        rho = variables["spearman"]["values"][0][j]
        row = next(line for line in table.splitlines() if line.startswith(f"| biofilm_volume | {parameter} |"))
        assert ("-" if rho is None else number(rho, 2)) in row.split("|")[-4], row  # the Spearman column


def test_convergence_json_holds_the_tables_levels(tiny_scene, tmp_path):
    result = invoke("convergence", tiny_scene, "-o", tmp_path / "conv", "--levels", "2", "--series", "time",
                    "--json", "-q")
    assert result.exit_code == 0, result.output
    record = _strict(result.stdout)
    variables = record["variables"]
    table = (tmp_path / "conv" / "convergence.md").read_text()
    for level in (0, 1):
        steps = variables["steps_taken"]["values"][0][level]
        assert f"| time | {level} | 256 |" in table and f"| {number(steps, 9)} |" in table


def test_json_has_no_nan_and_no_infinity():
    """NaN and infinities are null: every record reads with a strict JSON parser."""
    from biostudy.reports.records import text

    assert _strict(text({"a": float("nan"), "b": np.array([1.0, np.inf]), "c": np.float32(2.5)})) == \
        {"a": None, "b": [1.0, None], "c": 2.5}


def test_show_json_of_a_scene_file_is_refused_in_one_line(tiny_scene):
    result = invoke("show", "--json", tiny_scene)
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1, result.output
    assert "--json" in result.stderr and result.stdout == ""


PROGRESS = re.compile(r"T\* = [\d.e-]+ / 0\.2 \(\d+%\)")


def test_quiet_and_verbose_before_or_after_the_command(tiny_scene, tmp_path):
    """-q: no progress lines (the result's line stays); -v: the library's detail (the scene's size, where the
    time went); the same given before the command (every command) or after it."""
    plain = invoke("run", tiny_scene, "-o", tmp_path / "plain.nc")
    assert plain.exit_code == 0, plain.output
    detail = "tiny: 16 × 16 cells of 1 µm, 20 steps to T* = 0.2, 3 outputs"
    assert PROGRESS.search(plain.stderr) and detail not in plain.stderr
    for args in (["-q", "-v", "run", tiny_scene, "-o", tmp_path / "global.nc"],
                 ["run", tiny_scene, "-o", tmp_path / "command.nc", "-q", "-v"]):
        result = invoke(*args)
        assert result.exit_code == 0, result.output
        assert not PROGRESS.search(result.stderr) and "wrote" in result.stderr, result.stderr
        assert detail in result.stderr and re.search(r"tiny: wall time [\d.e-]+ s \(nutrient", result.stderr)
    assert [type(h).__name__ for h in logging.getLogger("biostudy").handlers] == ["NullHandler"]  # as it was


def test_the_library_prints_nothing_and_logs_to_its_logger(tiny_scene, tmp_path, capfd):
    """biostudy.run from Python: nothing on stdout or stderr (no handler is configured), while a handler the
    caller puts on the 'biostudy' logger gets what the run did and, at DEBUG, its detail."""
    import biostudy

    got: list[logging.LogRecord] = []
    handler = logging.Handler(logging.DEBUG)
    handler.emit = got.append  # type: ignore[method-assign]
    logger = logging.getLogger("biostudy")
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG)
    try:
        biostudy.run(tiny_scene, output=tmp_path / "run.nc")
    finally:
        logger.removeHandler(handler)
        logger.setLevel(logging.NOTSET)
    assert capfd.readouterr() == ("", "")
    said = [(r.levelno, r.getMessage()) for r in got]
    assert any(level == logging.INFO and message.startswith("tiny: 20 steps") and "wrote" in message
               for level, message in said), said
    assert any(level == logging.DEBUG and "16 × 16 cells" in message for level, message in said), said


def test_scenes_json_lists_what_the_table_lists(write_toml, tmp_path):
    write_toml("mine.toml", 'description = "my own scene"\n[grid]\nshape = [4, 4]\n')
    env = {"BIOSTUDY_STUDIES": str(tmp_path)}
    record = _strict(invoke("scenes", "--json", env=env).stdout)
    assert record["entries"] == [{"file": "mine.toml", "kind": "scene", "description": "my own scene"}]
    assert _rows(invoke("scenes", env=env).stdout, "file")["mine.toml"] == ["scene", "my own scene"]


def test_a_runs_warnings_reach_python_callers_as_warnings(tiny_scene, monkeypatch):
    """What `biostudy run` prints as 'warning: ...' (a vanished dense biofilm) is a Python warning from
    biostudy.run, as from sweep and calibrate."""
    import biostudy
    from biostudy.commands import run as command

    monkeypatch.setattr(command.Result, "warnings", lambda self: ["dense biofilm (phi >= 0.8) vanished"])
    with pytest.warns(UserWarning, match="dense biofilm"):
        biostudy.run(tiny_scene)
