"""Nothing lost, nothing hung (issue 10): every fault is injected, not assumed.

One test (or a few) per item of the issue, numbered as there: outputs that would overwrite an input or a
foreign file, temporaries of other writers, two sweeps and a foreign study in one directory, a case file
corrupted without changing its size, inf values, an unwritable output, a killed main process and killed
workers, an oversized grid, foreign datasets given to show/plot/export, mask paths and crafted .npy files,
errors blamed on the right file, the solver's convergence message, outdated cases.  Scenes are tiny (2-D 16²,
20 steps) unless a test needs a case that runs long enough to be killed; every process a test starts is
ended by the test, and every file stays in its temporary directory.
"""
from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from biostudy.cli import app

cli = CliRunner()


def invoke(*args):
    return cli.invoke(app, [str(a) for a in args])


def one_line_error(result) -> str:
    """The single line of a bad-input answer: exit 2, 'error: ...', no traceback, nothing on stdout."""
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.output and result.stdout == ""
    return lines[0]


# ---------------------------------------------------------------------------------------------
# 13. A linear solver's failure says what failed (the true-residual check), not "info 0"


def test_the_solver_says_which_check_failed(tiny_scene, tmp_path):
    result = invoke("run", tiny_scene, "-o", tmp_path / "o.nc", "-q", "--set", "params.r=1e7",
                    "--set", "numerics.max_substeps=50")
    assert result.exit_code == 1, result.output
    assert "BiCGSTAB did not converge: it stopped after" in result.stderr
    assert "on its own recursive residual, but the true residual |b - A x| = " in result.stderr
    assert "info 0" not in result.stderr
