"""The small refusals (issue 25, item 17): each bad input blames what is wrong, in its own words, and only that.

`--tasks 0` blames --tasks; a closed port is "nothing listens", at once; "did you mean" never offers the key
refused; a symbolic link loop (a scene, `-o`) is named as such; a warning raised while an input is read does
not come between the error lines (a command that goes on prints it as one "warning:" line); a calibration's
`box = nan` is not a finite number.
"""
from __future__ import annotations

import logging
import socket
import subprocess
import sys
import warnings
from pathlib import Path

from conftest import TINY_SCENE
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.execution import dask

cli = CliRunner()


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def lines_of(result, status: int = 2) -> list[str]:
    assert result.exit_code == status, result.output
    assert "Traceback" not in result.output, result.output
    return result.stderr.strip().splitlines()


def test_tasks_0_blames_tasks(tiny_study, tmp_path):
    lines = lines_of(invoke("sweep", tiny_study, "-o", tmp_path / "out", "--task", "0", "--tasks", "0"))
    assert len(lines) == 1 and lines[0].startswith("error: --tasks: give a whole number, 1 or more (got 0)"), lines


def test_a_closed_port_is_nothing_listening(tiny_study, tmp_path, monkeypatch):
    monkeypatch.setattr(dask, "CONNECT_TIMEOUT", 1.0)
    with socket.socket() as probe:  # a port that was free a moment ago: nothing listens there
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    lines = lines_of(invoke("sweep", tiny_study, "-o", tmp_path / "out", "--scheduler", address, "-q"))
    assert lines == [f"error: --scheduler: nothing listens at {address} (connection refused): is a Dask scheduler "
                     "running there?"]


def test_did_you_mean_never_offers_the_key_refused(tiny_scene, write_toml):
    misplaced = write_toml("misplaced.toml", TINY_SCENE.replace("spacing = 1.0", "spacing = 1.0\ng = 2.0"))
    for result in (invoke("run", misplaced), invoke("run", tiny_scene, "--set", "grid.g=1")):
        [line] = lines_of(result)
        assert line.endswith("grid.g: unknown key here (g is a key of another table)"), line
    [line] = lines_of(invoke("run", tiny_scene, "--set", "grid.spacin=1"))
    assert line.endswith("grid.spacin: unknown key (did you mean 'spacing'?)"), line


def test_a_symbolic_link_loop_is_named_as_such(tiny_scene, tiny_study, tmp_path, tiny_run):
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    loop = tmp_path / "a"
    said = f"{loop}: is a symbolic link loop (it leads back to itself)"
    for args in (["run", loop], ["run", tiny_scene, "-o", loop], ["sweep", tiny_study, "-o", loop],
                 ["run", tiny_scene, "--continue", loop, "--set", "time.t_end=1"]):
        assert lines_of(invoke(*args)) == [f"error: {said}"], args
    from biostudy.data import writing

    run = writing.write_atomic(tiny_run((8, 8)).assign_attrs(biostudy_version="0"), tmp_path / "run.nc")
    for kind in ("vtu", "tiff"):
        [line] = lines_of(invoke("export", run, loop, "--format", kind))
        assert f"{loop} is a symbolic link loop (it leads back to itself)" in line, line
    assert loop.is_symlink() and (tmp_path / "b").is_symlink()  # untouched


def noisy(load):
    """`load` (a scene's), warning first as numpy and tifffile do on a strange image."""
    def loaded(*args, **kwargs):
        warnings.warn("invalid value encountered in divide", RuntimeWarning, stacklevel=2)
        logging.getLogger("tifffile").warning("TiffPage 0: corrupted tile")
        return load(*args, **kwargs)

    return loaded


NOISY = f"""\
import sys
sys.path.insert(0, {str(Path(__file__).parent)!r})
import biostudy.commands.run as run
from test_small_refusals import noisy
run.load_scene = noisy(run.load_scene)
from biostudy.cli import app
app(sys.argv[1:], prog_name="biostudy")
"""


def test_warnings_while_an_input_is_read_do_not_come_between_the_error_lines(tiny_scene, write_toml, tmp_path,
                                                                            monkeypatch):
    bad = write_toml("bad.toml", TINY_SCENE.replace("g = 1e8", "g = -1.0\nr = -2.0"))
    refused = subprocess.run([sys.executable, "-c", NOISY, "run", str(bad)], capture_output=True, text=True,
                             timeout=300)  # the real stderr: Python prints warnings there itself
    lines = refused.stderr.strip().splitlines()
    assert refused.returncode == 2 and len(lines) == 2 and all(line.startswith("error: ") for line in lines), lines
    from biostudy.commands import run

    monkeypatch.setattr(run, "load_scene", noisy(run.load_scene))  # in-process: pytest holds the log records
    good = invoke("run", tiny_scene, "-o", tmp_path / "tiny.nc", "-q")
    said = good.stderr.strip().splitlines()
    assert good.exit_code == 0 and said[1:] == ["warning: invalid value encountered in divide (RuntimeWarning)"], said


def test_a_calibration_box_of_nan_is_not_a_finite_number(write_toml, tiny_scene, tmp_path):
    (tmp_path / "m.tsv").write_text("observableId\ttime\tmeasurement\tnoiseParameters\nbiomass\t0.1\t1.0\t0.1\n")
    calibration = write_toml("cal.toml", """\
        scene = "tiny.toml"
        [data]
        measurements = "m.tsv"
        [estimate]
        g = [1e7, 1e10, "log"]
        [method]
        name = "posterior"
        box = nan
        """)
    lines = lines_of(invoke("calibrate", calibration, "-o", tmp_path / "out"))
    assert lines == [f"error: {calibration}: method.box: must be a finite number (got nan)"], lines
