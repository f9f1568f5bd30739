"""The `biostudy` command line: run, show, scenes; exit statuses; the catalogue of bad input."""
import os
import pty
import re
import select
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import typer
import xarray as xr
from typer.testing import CliRunner

from biostudy.cli import app
from biostudy.data import reading

runner = CliRunner()


def invoke(*args, env=None):
    return runner.invoke(app, [str(a) for a in args], env=env)


def test_run_writes_the_dataset_with_overrides(tiny_scene, tmp_path):
    out = tmp_path / "run.nc"
    result = invoke("run", tiny_scene, "-o", out, "--set", "params.g=1e9", "--set", "grid.shape=[18,16]",
                    "--set", "mechanics.enabled=false")
    assert result.exit_code == 0, result.output
    assert "wrote" in result.stderr and "20 steps" in result.stderr
    ds = xr.open_dataset(out)  # the run keeps its shape: each overridden key a scalar coordinate, no dimension
    assert ds.attrs["g"] == 1e9 and dict(ds.sizes) == {"time": 3, "y": 16, "x": 18, "bounds": 2}
    assert ds.phi.dims == ("time", "y", "x") and ds.g.dims == () and float(ds.g) == 1e9
    assert ds.grid_shape.item() == "18x16" and ds.mechanics_enabled.item() == 0
    assert dict(reading.open_dataset(out).sizes) == {"time": 3, "y": 16, "x": 18, "bounds": 2}
    assert '"params.g" = 1e+09' in ds.attrs["overrides"] and "shape = [18, 16]" in ds.attrs["scene"]
    assert sorted(os.listdir(tmp_path)) == ["run.nc", "tiny.toml"]


def test_run_on_threads_records_them_and_refuses_none(tiny_scene, tmp_path):
    """--threads sets the run's threads (recorded beside its cost), instead of the scene's; 0 is bad input."""
    result = invoke("run", tiny_scene, "-o", tmp_path / "two.nc", "--threads", "2", "--set", "numerics.threads=5")
    assert result.exit_code == 0, result.output
    assert xr.open_dataset(tmp_path / "two.nc").attrs["threads"] == 2
    refused = invoke("run", tiny_scene, "-o", tmp_path / "none.nc", "--threads", "0")
    assert refused.exit_code == 2 and "--threads" in refused.stderr and not (tmp_path / "none.nc").exists()


def test_run_defaults_to_the_scene_name_in_the_working_directory(tiny_scene, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke("run", "tiny.toml", "-q")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "tiny.nc").is_file()


def test_show_summarises_a_run(tiny_scene, tmp_path):
    out = tmp_path / "run.nc"
    assert invoke("run", tiny_scene, "-o", out, "-q").exit_code == 0
    result = invoke("show", out)
    assert result.exit_code == 0, result.output
    text = result.stdout
    for expected in ("tiny", "tiny test scene", "16 × 16 cells", "g = 1e8 1/T*", "wall time", "20 taken",
                     "phi_mean", "c_mean", "biofilm_volume", "T* = 0.2", "fipy"):
        assert expected in text, expected
    ds = xr.open_dataset(out)
    assert f"{ds.phi_mean.values[-1]:.4g}" in text


def test_scenes_lists_the_bundled_files_with_descriptions(write_toml, tmp_path):
    result = invoke("scenes")
    assert result.exit_code == 0
    text = " ".join(result.stdout.split())
    assert "directional.toml" in text and "nutrient" in text
    assert "directional-sweep.toml" in result.stdout
    write_toml("mine.toml", 'description = "my own scene"\n[grid]\nshape = [4, 4]\n')
    mine = invoke("scenes", env={"BIOSTUDY_STUDIES": str(tmp_path)})
    assert "mine.toml" in mine.stdout and "my own scene" in mine.stdout and "directional" not in mine.stdout


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # the overflow this case is built on
def test_a_failed_simulation_exits_1_and_keeps_what_it_computed_but_no_earlier_result(tiny_scene, tmp_path):
    """A run that stops writes its outputs up to there, marked incomplete (issue 33.3), nothing else; over an
    earlier result of the scene it writes nothing, and that result stays as it was."""
    out = tmp_path / "fail.nc"
    result = invoke("run", tiny_scene, "-o", out, "-q", "--set", "params.k_alpha=1e100",
                    "--set", "numerics.max_substeps=40")
    assert result.exit_code == 1
    assert result.stderr.startswith(f"error: simulation failed: {tiny_scene}: t = ")
    assert "Traceback" not in result.output and "(marked incomplete)" in result.stderr
    assert sorted(os.listdir(tmp_path)) == ["fail.nc", "tiny.toml"] and "incomplete" in xr.open_dataset(out).attrs
    out.unlink()
    assert invoke("run", tiny_scene, "-o", out, "-q").exit_code == 0
    before = out.read_bytes()
    again = invoke("run", tiny_scene, "-o", out, "-q", "--set", "params.k_alpha=1e100")
    assert again.exit_code == 1 and "the earlier result at" in again.stderr and out.read_bytes() == before


def _write_mask(tmp_path, shape):
    np.save(tmp_path / "mask.npy", np.ones(shape, bool))


# Each entry: id, command line (with {scene}, {study}, {dir} placeholders), what the one line must contain.
BAD_INPUT = [
    ("unknown key", ["run", "{scene}", "--set", "params.gamma=1"], ["--set: params.gamma", "unknown key"]),
    ("wrong type", ["run", "{scene}", "--set", "grid.spacing='one'"], ["--set: grid.spacing", "valid number"]),
    ("negative diffusivity", ["run", "{scene}", "--set", "params.d=-1"], ["--set: params.d: must be > 0 (got -1)"]),
    ("Poisson ratio 0.5", ["run", "{scene}", "--set", "params.nu=0.5"], ["params.nu: must be < 0.5"]),
    ("shape outside the grid", ["run", "{scene}", "--set", "biofilm.0.center=[30.0, 8.0]"],
     ["--set: biofilm[0].center", "outside the grid"]),
    ("source inside an obstacle", ["run", "{scene}", "--set", "obstacle.0.upper=[16.0, 16.0]"],
     ["{scene}", "nutrient[0]", "inside obstacle[0]"]),
    ("missing mask file", ["run", "{scene}", "--set", "obstacle.0={shape='mask', path='gone.npy'}"],
     ["--set: obstacle[0].path", "not found"]),
    ("mask of the wrong shape", ["run", "{scene}", "--set", "obstacle.0={shape='mask', path='mask.npy'}"],
     ["--set: obstacle[0].path", "array has shape [4, 4]"]),
    ("output time after t_end", ["run", "{scene}", "--set", "time.output_times=[0.0, 5.0]"],
     ["time.output_times[1]", "outside [0, t_end = 0.2]"]),
    ("zero steps", ["run", "{scene}", "--set", "time.steps=0"], ["time.steps: must be >= 1 (got 0)"]),
    ("unknown shape", ["run", "{scene}", "--set", "biofilm.0.shape='cone'"], ["biofilm[0]", "unknown shape 'cone'"]),
    ("unknown consumption law", ["run", "{scene}", "--set", "model.consumption=second-order"],
     ["model.consumption: must be 'first-order' or 'zero-order'"]),
    ("unknown expansion law", ["run", "{scene}", "--set", "model.expansion=eq35"],
     ["model.expansion: must be 'eq36' or 'table1'"]),
    ("malformed --set", ["run", "{scene}", "--set", "params.g"], ["--set", "expected KEY=VALUE"]),
    ("missing scene file", ["run", "{dir}/nowhere.toml"], ["nowhere.toml: no such file"]),
    ("TOML syntax error", ["run", "{dir}/broken.toml"], ["broken.toml: not valid TOML", "line 2"]),
    ("study given to run", ["run", "{study}"], ["{study}", "this is a study file"]),
    ("scene given to sweep", ["sweep", "{scene}"], ["{scene}", "this is a scene file"]),
    ("sweep value not a list", ["sweep", "{dir}/notlist.toml"], ["notlist.toml: sweep.g: must be a non-empty list"]),
    ("invalid case in a sweep", ["sweep", "{dir}/negative.toml"],
     ["negative.toml: case r=-5: params.r: must be >= 0 (got -5)"]),
    ("both --workers and --scheduler", ["sweep", "{study}", "--workers", "2", "--scheduler", "tcp://x:1"],
     ["--workers", "not both"]),
    ("tls:// without a TLS configuration", ["sweep", "{study}", "--scheduler", "tls://127.0.0.1:9"],
     ["--scheduler: tls://127.0.0.1:9 needs a TLS configuration", "distributed.comm.tls.ca-file", "docs/clusters.md"]),
    ("misspelled bundled scene", ["run", "directonal"],
     ["directonal: no such file", "did you mean 'directional'?", "`biostudy scenes`"]),
    ("misspelled bundled study", ["sweep", "directional-swep"], ["did you mean 'directional-sweep'?"]),
    ("show a file that is not netCDF", ["show", "{dir}/mask.npy"], ["mask.npy", "not a netCDF dataset"]),
]


@pytest.mark.parametrize("args, expected", [(a, e) for _, a, e in BAD_INPUT], ids=[k for k, _, _ in BAD_INPUT])
def test_bad_input_is_one_line_exit_2_no_traceback(tiny_scene, tiny_study, write_toml, tmp_path, args, expected):
    _write_mask(tmp_path, (4, 4))
    write_toml("broken.toml", "[grid]\nshape = = [4, 4]\n")
    write_toml("notlist.toml", 'scene = "tiny.toml"\n[sweep]\ng = 1e8\n')
    write_toml("negative.toml", 'scene = "tiny.toml"\n[sweep]\nr = [5.0, -5.0]\n')
    fill = {"{scene}": str(tiny_scene), "{study}": str(tiny_study), "{dir}": str(tmp_path)}

    def filled(text):
        for k, v in fill.items():
            text = text.replace(k, v)
        return text

    output = [] if args[0] == "show" else ["-o", tmp_path / "out"]
    result = invoke(*(filled(a) for a in args), *output)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    for part in expected:
        assert filled(part) in lines[0], lines[0]
    assert "Traceback" not in result.output and result.stdout == ""
    assert not (tmp_path / "out").exists()


def test_sigterm_during_a_run_leaves_no_file(tmp_path):
    """SIGTERM mid-run: exit 143 (128 + 15), no dataset and no temporary left (a file is complete or absent).

    The run's progress bar goes to a terminal (a pseudo-terminal here), so the signal is sent as soon as
    it shows steps being taken: mid-run on a fast machine or a slow one, instead of after a guessed delay."""
    out = tmp_path / "directional.nc"
    terminal, its_end = pty.openpty()
    process = subprocess.Popen([sys.executable, "-m", "biostudy", "run", "directional", "-o", str(out),
                                "--set", "time.steps=3000"], cwd=tmp_path, stdin=subprocess.DEVNULL,
                               stdout=subprocess.DEVNULL, stderr=its_end)
    os.close(its_end)
    shown = _read_until(terminal, rb"steps [1-9]", process, timeout=600)  # a hang guard, not a speed bar
    assert process.poll() is None, shown
    process.send_signal(signal.SIGTERM)
    process.wait(timeout=600)
    shown += _read_until(terminal, None, process, timeout=5)
    os.close(terminal)
    text = shown.decode(errors="replace")
    assert process.returncode == 143, text[-300:]
    assert "interrupted" in text and "Traceback" not in text, text[-300:]
    assert os.listdir(tmp_path) == []


def _read_until(terminal: int, pattern: bytes | None, process, timeout: float) -> bytes:
    """What a process writes to the terminal, until `pattern` shows (None: until it has gone quiet)."""
    seen, deadline = b"", time.monotonic() + timeout
    while time.monotonic() < deadline and not (pattern and re.search(pattern, seen)):
        ready, _, _ = select.select([terminal], [], [], 0.2)
        if not ready:
            if pattern is None and process.poll() is not None:
                break
            continue
        try:
            seen += os.read(terminal, 65536)
        except OSError:  # the process closed the terminal: nothing more to read
            break
    if pattern and not re.search(pattern, seen):
        raise AssertionError(f"no {pattern!r} within {timeout} s: {seen[-500:]!r}")
    return seen


def test_importing_sets_nothing_and_the_command_pins_the_solver_suite(tiny_scene, tmp_path):
    """No side effects on import: FiPy's solver suite and the picture backend are set where a biostudy
    process starts (the command, a worker), not by importing solver or biostudy."""
    env = {k: v for k, v in os.environ.items() if k not in ("FIPY_SOLVERS", "MPLBACKEND")}
    imported = subprocess.run([sys.executable, "-c", "import os, solver, biostudy.cli, biostudy.execution.jobs, "
                               "biostudy.plots; print(sorted({'FIPY_SOLVERS', 'MPLBACKEND'} & set(os.environ)))"],
                              env=env, capture_output=True, text=True, check=True)
    assert imported.stdout.strip() == "[]"
    out = tmp_path / "run.nc"
    subprocess.run([sys.executable, "-m", "biostudy", "run", str(tiny_scene), "-o", str(out), "-q"], env=env,
                   check=True, capture_output=True)
    assert xr.open_dataset(out).attrs["fipy_solvers"] == "scipy"


def test_version_short_help_completion_and_metavars():
    from importlib.metadata import version

    shown = invoke("--version")
    assert shown.exit_code == 0 and shown.stdout == f"biostudy {version('biostudy')}\n"
    wide = {"COLUMNS": "160"}
    top = invoke("-h", env=wide)
    assert top.exit_code == 0 and "--install-completion" in top.stdout and "--version" in top.stdout
    takes = {"run": {"--set": "KEY=VALUE", "--output": "OUT.nc"},
             "sweep": {"--set": "KEY=VALUE", "--workers": "N", "--scheduler": "ADDRESS", "--output": "DIR"},
             "convergence": {"--levels": "N", "--set": "KEY=VALUE"}, "plot": {"--time": "T"}}
    for command, options in takes.items():
        result = invoke(command, "-h", env=wide)
        assert result.exit_code == 0 and "Usage: biostudy " + command in result.stdout
        rows = {line.split()[1]: line for line in result.stdout.splitlines() if line.startswith("│ --")}
        for option, metavar in options.items():
            assert f" {metavar} " in rows[option], rows[option]
        flags = [o for o in ("--quiet", "--retry-failed") if o in rows]
        assert all("<bool>" not in rows[o] for o in flags), flags  # a flag takes no value
        assert "--quiet" in flags  # every command takes -q after it (issue 39.12)


def test_an_incomplete_scene_tells_every_problem_one_line_each(write_toml, tmp_path):
    scene = write_toml("incomplete.toml", """\
        name = "incomplete"
        [params]
        d = -1
        g = -2
        [time]
        steps = 0
        """)
    result = invoke("run", scene, "-o", tmp_path / "out.nc")
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert result.stderr.splitlines() == [f"error: {scene}: grid: required key is missing",
                                          f"error: {scene}: params.d: must be > 0 (got -1)",
                                          f"error: {scene}: params.g: must be >= 0 (got -2)",
                                          f"error: {scene}: time.steps: must be >= 1 (got 0)"]


PROGRESS = re.compile(r"tiny: T\* = [\d.e-]+ / 0\.2 \((\d+)%\), steps \d+, bisections \d+, elapsed [\d.]+ s"
                      r"(, left (~[\d.]+|<1) s)?")


def test_progress_without_a_terminal_is_plain_lines(tiny_scene, tiny_study, tmp_path):
    """A batch job or `| tee`: stderr is a pipe, so progress comes as plain lines (no escape codes), every tenth
    of the run; a sweep says how many cases are done; a sweep with nothing left to run says so."""
    out = tmp_path / "run.nc"
    ran = subprocess.run([sys.executable, "-m", "biostudy", "run", str(tiny_scene), "-o", str(out)],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    assert "\x1b" not in ran.stderr
    lines = ran.stderr.splitlines()
    percents = [int(PROGRESS.fullmatch(line).group(1)) for line in lines[:-1]]
    assert percents == list(range(10, 101, 10)), lines
    assert lines[-1].startswith(f"wrote {out}")
    # the file's CF history is the command line that made it
    history = xr.open_dataset(out).attrs["history"]
    assert history.endswith(f": biostudy run {tiny_scene} -o {out}"), history

    command = ["sweep", tiny_study, "-o", tmp_path / "sweep", "--set", "time.steps=4"]
    swept = invoke(*command)  # in-process: CliRunner's stderr is not a terminal either
    assert swept.exit_code == 0, swept.stderr
    assert "\x1b" not in swept.stderr
    done = [line for line in swept.stderr.splitlines() if line.startswith("tiny-sweep: ")]
    assert [line.split(" cases ")[0] for line in done] == [f"tiny-sweep: {k}/4" for k in range(1, 5)], done
    again = invoke(*command)
    assert again.exit_code == 0 and "\x1b" not in again.stderr
    assert again.stderr.splitlines()[0] == "nothing to run: all 4 cases finished before", again.stderr
    assert "0/0" not in again.stderr


def test_shell_completion_offers_bundled_names_by_kind():
    def offered(words: str) -> list[str]:
        env = {"_BIOSTUDY_COMPLETE": "complete_bash", "COMP_WORDS": words, "COMP_CWORD": str(len(words.split()) - 1)}
        result = runner.invoke(app, [], env=env, prog_name="biostudy")
        assert result.exit_code == 0, result.output
        return result.stdout.split()

    assert offered("biostudy run direc") == ["directional", "directional2d"]  # scenes only, not the studies
    assert offered("biostudy sweep direc") == ["directional-sensitivity", "directional-sweep"]
    assert offered("biostudy stability st") == ["stability"]
    assert "agar-g1e8" in offered("biostudy convergence a")


def test_every_command_takes_quiet_and_verbose_after_it_as_the_readme_says(tiny_scene, capsys):
    """Issue 39.12: show, scenes, analyze, plot and export refused `-q` and `-v` after the command ("No such
    option: -q") though the README says they work before or after it; every command takes them."""
    from biostudy.cli.logs import is_quiet

    group = typer.main.get_command(app)
    commands = group.commands  # type: ignore[attr-defined]
    assert len(commands) >= 11
    for name, command in commands.items():  # as click parses them (rendering 22 helps took 1.5 s)
        flags = {flag for parameter in command.params for flag in parameter.opts}
        assert {"-q", "--quiet", "-v", "--verbose"} <= flags, (name, sorted(flags))
    listed = invoke("scenes", "--verbose")
    assert listed.exit_code == 0 and "agar" in listed.stdout, listed.output
    shown = invoke("show", tiny_scene, "-q")
    assert shown.exit_code == 0 and "memory" in shown.stdout and not is_quiet()  # the setting ends with the command
