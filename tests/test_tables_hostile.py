"""Measurement tables and the files read beside them, as a hostile user hands them in (issue 25, items 4, 9, 13
and the table parts of 17): no hang, no memory run-away, no traceback, one line per problem and a bounded number
of lines.

The calibration is the tiny scene (2-D 16², T* = 0 to 0.2) with g estimated; nothing here simulates: `show`
and `calibrate` refuse before anything runs.  A test that would hang (a FIFO) fails after 30 s, one that would
fill the memory (/dev/zero) after 2 GiB (`hang_guard`); a pint expression that computes for ever cannot be
interrupted by a signal, so that one runs in a process of its own with a deadline.
"""
from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import TINY_SCENE
from typer.testing import CliRunner

from biostudy.calibration import measurements
from biostudy.calibration.measurements import read_measurements
from biostudy.calibration.problem import load_calibration
from biostudy.calibration.table import DataSpec
from biostudy.cli import app
from biostudy.errors import BadInput
from biostudy.execution import dask

cli = CliRunner()
HEADER = "observableId\ttime\tmeasurement\tnoiseParameters\n"
TABLE = HEADER + "biomass\t0.05\t2.9\t0.15\nbiomass\t0.1\t3.7\t0.18\n"


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def error_lines(result) -> list[str]:
    """The lines of a refusal: exit status 2, each line 'error: ...', no traceback."""
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert lines and all(line.startswith("error: ") for line in lines), result.stderr
    assert "Traceback" not in result.output
    return lines


@pytest.fixture
def hang_guard():
    """A test that would hang in a blocking open or read fails after 30 s instead (SIGALRM interrupts it), and
    one that would read /dev/zero into memory fails with MemoryError 2 GiB later (the address space of this
    process is bounded while it runs)."""
    def expire(signum, frame):
        raise TimeoutError("hung")

    previous = signal.signal(signal.SIGALRM, expire)
    limits = resource.getrlimit(resource.RLIMIT_AS)
    used = int(Path("/proc/self/statm").read_text().split()[0]) * resource.getpagesize()
    resource.setrlimit(resource.RLIMIT_AS, (used + (2 << 30), limits[1]))
    signal.alarm(30)
    yield
    signal.alarm(0)
    resource.setrlimit(resource.RLIMIT_AS, limits)
    signal.signal(signal.SIGALRM, previous)


@pytest.fixture
def calibration(tmp_path):
    """calibration(table=TABLE, data=extra [data] lines, name="t.tsv") -> a calibration file of the tiny scene
    whose table holds `table` (None: the table is left for the test to make)."""
    (tmp_path / "tiny.toml").write_text(TINY_SCENE)

    def write(table: str | None = TABLE, data: str = "", name: str = "t.tsv") -> Path:
        if table is not None:
            (tmp_path / name).write_text(table, encoding="utf-8")
        path = tmp_path / "c.toml"
        path.write_text(f'scene = "tiny.toml"\n[data]\nmeasurements = "{name}"\n{data}\n'
                        '[estimate]\ng = [1e7, 1e9, "log"]\n')
        return path

    return write


# ---------------------------------------------------------------------------------------------
# 4. The table and the scheduler file are regular files of bounded size, checked before they are opened


@pytest.mark.parametrize("kind", ["fifo", "device", "directory", "too big"])
def test_a_table_that_is_no_regular_file_or_too_big_is_one_line_to_show_and_calibrate(kind, calibration, tmp_path,
                                                                                    monkeypatch, hang_guard):
    table = {"device": Path("/dev/zero")}.get(kind, tmp_path / "t.tsv")
    path = calibration(None, name=str(table))
    if kind == "fifo":
        os.mkfifo(table)
    elif kind == "directory":
        table.mkdir()
    elif kind == "too big":
        monkeypatch.setattr(measurements, "TABLE_BYTES", 1024)
        table.write_text(TABLE + "biomass\t0.15\t4.0\t0.2\n" * 60)
    what = {"fifo": "is a FIFO (named pipe), not a measurement table",
            "device": "is a character device, not a measurement table",
            "directory": "is a directory, not a measurement table",
            "too big": "KiB; a measurement table may hold at most 1 KiB"}[kind]
    for command in (("show", path), ("calibrate", path, "-q", "-o", tmp_path / "out")):
        lines = error_lines(invoke(*command))
        assert len(lines) == 1 and lines[0].startswith(f"error: {table}: ") and what in lines[0], lines
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["fifo", "device", "too big"])
def test_a_scheduler_file_that_is_no_regular_file_or_too_big_is_one_line(kind, calibration, tiny_study, tmp_path,
                                                                         monkeypatch, hang_guard):
    scheduler = {"device": Path("/dev/zero")}.get(kind, tmp_path / "scheduler.json")
    if kind == "fifo":
        os.mkfifo(scheduler)
    elif kind == "too big":
        monkeypatch.setattr(dask, "SCHEDULER_FILE_BYTES", 1024)
        scheduler.write_text('{"address": "tcp://127.0.0.1:8786", "workers": "' + "w" * 2048 + '"}')
    what = {"fifo": "is a FIFO (named pipe), not a Dask scheduler file",
            "device": "is a character device, not a Dask scheduler file",
            "too big": "KiB; a Dask scheduler file may hold at most 1 KiB"}[kind]
    for command in (("sweep", tiny_study), ("calibrate", calibration())):
        lines = error_lines(invoke(*command, "-q", "-o", tmp_path / "out", "--scheduler-file", scheduler))
        assert len(lines) == 1 and lines[0].startswith(f"error: {scheduler}: --scheduler-file: "), lines
        assert what in lines[0], lines
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["scheduler file", "scene"])
def test_json_or_toml_nested_too_deeply_is_one_line(kind, tmp_path):
    if kind == "scheduler file":
        (tmp_path / "s.json").write_text("[" * 100_000)
        line = error_lines(invoke("sweep", tmp_path / "none.toml", "--scheduler-file", tmp_path / "s.json"))
        assert line == [f"error: {tmp_path / 's.json'}: --scheduler-file: not a Dask scheduler file (nested too "
                        "deeply)"]
    else:
        (tmp_path / "s.toml").write_text("a = " + "[" * 100_000)
        line = error_lines(invoke("show", tmp_path / "s.toml"))
        assert line == [f"error: {tmp_path / 's.toml'}: not valid TOML: arrays or tables nested too deeply"]


# ---------------------------------------------------------------------------------------------
# 9. A time_unit or t_ref pint cannot read as a time is one line naming the key


@pytest.mark.parametrize("unit, t_ref, key", [
    ("h", "48 h)", "t_ref"), ("h", "'48 h'", "t_ref"), ("h)", "48 h", "time_unit"), ("h", "(48 h", "t_ref"),
    ("h", "48 h +", "t_ref"), ("h", "48 h**", "t_ref"), ("h", "48 * * h", "t_ref"), ("h", "", "t_ref"),
    ("", "48 h", "time_unit"), ("h", "48 m", "t_ref"), ("h", "x" * 300, "t_ref"), ("h", "1e-320 h", "t_ref")])
def test_a_time_pint_cannot_read_is_one_line_naming_the_key(unit, t_ref, key, calibration):
    path = calibration(data=f"time_unit = {json.dumps(unit)}\nt_ref = {json.dumps(t_ref)}\n")
    lines = error_lines(invoke("show", path))
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: data.{key}: "), lines


def test_a_time_pint_would_compute_forever_is_refused_at_once():
    code = ("from biostudy.inputs.real_time import in_t_star as factor\nfrom biostudy.errors import InvalidAt\n"
            "try:\n    factor('h', '10**10**10 h')\n"
            "except InvalidAt as error:\n    print(error.key, error.problem)\n")
    try:
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("t_ref = '10**10**10 h' was still being computed after 60 s")
    assert done.returncode == 0 and done.stdout.startswith("t_ref "), done.stdout + done.stderr


def test_valid_times_read_as_before():
    assert DataSpec(measurements="t.tsv", time_unit="h", t_ref="48 h").time_factor() == pytest.approx(1 / 48)
    assert DataSpec(measurements="t.tsv", time_unit="min", t_ref="2 d").time_factor() == pytest.approx(1 / 2880)
    assert DataSpec(measurements="t.tsv", time_unit="hour", t_ref="1.5e1 hours").time_factor() == pytest.approx(
        1 / 15)


# ---------------------------------------------------------------------------------------------
# 13. Numbers as a lab writes them: ASCII digits, a point, an exponent


@pytest.mark.parametrize("text", ["3_4", "\u0663", "\u0663.5", "\uff13", "1_000.5", "0x1p3", "1e", "--1", "1.2.3",
                                  "3,7", "inf", "-Infinity", "nan", "1e999"])
def test_a_number_no_lab_writes_is_refused_not_read(text, tmp_path):
    table = tmp_path / "t.tsv"
    table.write_text(TABLE.replace("3.7", text), encoding="utf-8")
    with pytest.raises(BadInput) as refused:
        read_measurements(table)
    problem = "must be a finite number" if text in ("inf", "-Infinity", "nan", "1e999") else "not a number"
    comma = ": decimal commas are read in ';'-separated tables only" if text == "3,7" else ""
    assert refused.value.lines() == [f"{table}: line 3: measurement: {problem} (got {text!r}){comma}"]


@pytest.mark.parametrize("text, value", [("3", 3.0), ("-3.5", -3.5), ("+.5", 0.5), ("5.", 5.0), ("1e-3", 1e-3),
                                         ("2.5E+2", 250.0), ("007", 7.0)])
def test_numbers_a_lab_writes_are_read(text, value, tmp_path):
    table = tmp_path / "t.tsv"
    table.write_text(TABLE.replace("3.7", text))
    assert read_measurements(table)[1].value == value


# ---------------------------------------------------------------------------------------------
# 17. Many bad rows are a bounded number of lines; ';' tables; a time just past the end unrounded


@pytest.mark.parametrize("bad, where, rows", [
    ("biomass\t0.1\tx\t0.1\n", "measurement: not a number", 25_000),
    ("biomas\t0.1\t3.0\t0.1\n", "observableId: unknown observable", 2_000)])  # checked against the scene
def test_many_bad_rows_are_a_bounded_number_of_lines_and_a_count(bad, where, rows, calibration):
    path = calibration(HEADER + bad * rows)
    lines = error_lines(invoke("show", path))
    assert len(lines) == measurements.SHOWN_PROBLEMS + 1 and all(where in line for line in lines[:-1]), lines[:3]
    assert lines[-1].endswith(f"t.tsv: … and {rows - measurements.SHOWN_PROBLEMS:,} more problems"), lines[-1]


def test_a_header_of_a_hundred_thousand_columns_is_a_few_lines_at_once(tmp_path):
    table = tmp_path / "t.tsv"
    table.write_text(HEADER.replace("\n", "\tx" * 100_000 + "\ttime\n") + "biomass\t0.1\t3.0\t0.1\n")
    with pytest.raises(BadInput) as refused:
        read_measurements(table)
    assert refused.value.lines() == [f"{table}: unknown column 'x' (PEtab's measurement table: observableId, time, "
                                     "measurement, noiseParameters, optionally simulationConditionId, datasetId, "
                                     f"replicateId, datapointId)", f"{table}: column 'time' comes twice",
                                     f"{table}: column 'x' comes 100,000 times"]


def test_line_numbers_are_an_editors_whatever_unicode_calls_a_line_break(tmp_path):
    table = tmp_path / "t.tsv"
    table.write_text(TABLE.replace("biomass\t0.05", "bio\u2028mass\f\x1c\t0.05").replace("3.7", "x"))
    with pytest.raises(BadInput) as refused:
        read_measurements(table)
    assert refused.value.lines() == [f"{table}: line 3: measurement: not a number (got 'x')"]


def _semicolons(text: str, decimal: str = ".") -> str:
    return text.replace("\t", ";").replace(".", decimal)


@pytest.mark.parametrize("name, table", [
    ("t.csv", _semicolons(TABLE)), ("t.csv", _semicolons(TABLE, ",")), ("t.txt", _semicolons(TABLE, ",")),
    ("t.csv", '"observableId";"time";"measurement";"noiseParameters"\n"biomass";0,05;2,9;0,15\n'
              '"biomass";0,1;3,7;0,18\n')], ids=["points", "decimal commas", "no suffix", "quoted"])
def test_a_semicolon_table_is_read_as_such_with_its_decimal_commas(name, table, tmp_path):
    (tmp_path / "t.tsv").write_text(TABLE)
    (tmp_path / name).write_text(table)
    assert read_measurements(tmp_path / name) == read_measurements(tmp_path / "t.tsv")


def test_a_semicolon_table_mixing_decimal_commas_and_points_is_refused(tmp_path):
    table = tmp_path / "t.csv"
    table.write_text(_semicolons(TABLE, ",").replace("3,7", "1.000"))
    with pytest.raises(BadInput) as refused:
        read_measurements(table)
    assert refused.value.lines() == [f"{table}: line 3: measurement: '1.000' has a point where this table writes "
                                     "decimals with a comma (line 2: time); a thousands separator is not read"]


@pytest.mark.parametrize("data, time, shown", [
    ("", "0.2000001", "0.2000001 is T* = 0.2000001, after the run's end: the scene runs over T* = 0 to 0.2 "),
    ('time_unit = "h"\nt_ref = "20 h"', "4.000001",
     "4.000001 h is T* = 0.2000001 (t_ref = 20 h), after the run's end: the scene runs over T* = 0 to 0.2 "),
    ('time_unit = "h"\nt_ref = "20 h"', "30", "30 h is T* = 1.5 (t_ref = 20 h), after the run's end")])
def test_a_time_just_past_the_end_is_told_unrounded(data, time, shown, calibration):
    path = calibration(TABLE.replace("0.1\t3.7", f"{time}\t3.7"), data)
    lines = error_lines(invoke("show", path))
    assert len(lines) == 1 and f"t.tsv: line 3: time: {shown}" in lines[0], lines


def test_a_spreadsheets_unicode_text_export_is_read(tmp_path):
    (tmp_path / "t.tsv").write_text(TABLE)
    (tmp_path / "excel.txt").write_bytes(TABLE.encode("utf-16"))  # Excel's "Unicode text": UTF-16 with its mark
    assert read_measurements(tmp_path / "excel.txt") == read_measurements(tmp_path / "t.tsv")


def test_a_cell_beyond_csvs_field_limit_is_one_line(tmp_path):
    table = tmp_path / "long.tsv"
    table.write_text(TABLE.replace("3.7", "3" * 200_000))
    with pytest.raises(BadInput) as refused:
        read_measurements(table)
    assert refused.value.lines() == [f"{table}: line 3: cannot be read as a table (field larger than field limit "
                                     "(131072))"]


def test_the_table_of_a_valid_calibration_reads_as_before(calibration):
    plan = load_calibration(calibration(_semicolons(TABLE), 'time_unit = "h"\nt_ref = "2 h"', name="t.csv"))
    assert [(m.line, m.observable, m.time, m.value, m.sigma) for m in plan.measurements] == [
        (2, "biomass", 0.05, 2.9, 0.15), (3, "biomass", 0.1, 3.7, 0.18)]
    assert list(plan.times) == [0.025, 0.05]


def test_a_set_value_nested_too_deeply_is_one_line(tmp_path):
    scene = tmp_path / "tiny.toml"
    scene.write_text(TINY_SCENE)
    line = error_lines(invoke("run", scene, "-o", tmp_path / "x.nc", "--set", "params.g=" + "[" * 100_000))
    assert line == ["error: --set: the value of params.g is nested too deeply to be read"]


def test_petabs_optional_columns_are_read_and_pre_equilibration_refused_where_given(tmp_path):
    table = tmp_path / "t.tsv"
    header = ("observableId\tpreequilibrationConditionId\tsimulationConditionId\ttime\tmeasurement\t"
              "observableParameters\tnoiseParameters\tdatasetId\treplicateId\tdatapointId\n")
    table.write_text(header + "biomass\t\t\t0.05\t2.9\t\t0.15\tday1\trep2\tp7\n")
    row, = read_measurements(table)
    assert (row.dataset, row.replicate, row.datapoint, row.value) == ("day1", "rep2", "p7", 2.9)
    table.write_text(header + "biomass\tsteady\t\t0.05\t2.9\tscale\t0.15\t\t\t\n")
    with pytest.raises(BadInput) as refused:
        read_measurements(table)
    assert refused.value.lines() == [
        f"{table}: line 2: preequilibrationConditionId: pre-equilibration is not supported (leave the column empty) "
        "(got 'steady')",
        f"{table}: line 2: observableParameters: the observables have no parameters (leave the column empty) "
        "(got 'scale')"]
