"""Output for scripts and logs (issue 27, item 5): tables never cut when not on a terminal, `--json`, and
`-q`/`-v` with the `logging` module."""
from __future__ import annotations

from typer.testing import CliRunner

from biostudy.cli import app

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
