"""Every command declared once (issue 38.2): the command line and the Python functions are made from the same
declarations (`biostudy.commands.declared`), take the same options with the same defaults, and say the same
words for the same mistake."""
from __future__ import annotations

import importlib
import inspect

import pytest
import typer
from typer.testing import CliRunner

import biostudy
from biostudy.cli import app
from biostudy.commands import declared
from biostudy.commands.options import REQUIRED
from biostudy.errors import BadInput

OWN = {"quiet", "verbose", "as_json", "help"}  # the command line's own: how it prints


def test_the_command_line_and_python_take_every_option_with_its_default_from_the_declaration():
    group = typer.main.get_command(app)
    assert set(group.commands) == {c.name for c in declared.COMMANDS}
    for command in declared.COMMANDS:
        cli = {p.name: p for p in group.commands[command.name].params if p.name not in OWN}
        python = inspect.signature(getattr(biostudy, command.name)).parameters
        assert list(cli) == [o.name for o in command.on("cli")], command.name
        assert list(python) == [o.name for o in command.on("python")], command.name
        for option in command.options:
            assert option.side in ("", "cli", "python") and (option.why or not option.side), (command.name, option)
            if option.side != "python":  # the command line's spelling, help and default
                param = cli[option.name]
                assert tuple(param.opts) == (option.flags or (option.name,)), (command.name, option.name)
                assert option.help in (param.help or ""), (command.name, option.name)
                if option.default is REQUIRED:
                    assert param.required, (command.name, option.name)
                else:
                    assert option.value(param.default, cli=True) == option.value(option.default, cli=False)
            if option.side != "cli":  # Python's: positional where declared, the same default
                param = python[option.name]
                expected = (inspect.Parameter.VAR_POSITIONAL if option.variadic else
                            inspect.Parameter.POSITIONAL_OR_KEYWORD if option.positional else
                            inspect.Parameter.KEYWORD_ONLY)
                assert param.kind is expected, (command.name, option.name)
                assert param.default is (inspect.Parameter.empty if option.default is REQUIRED or option.variadic
                                         else option.default), (command.name, option.name)
                assert option.help in biostudy.__getattr__(command.name).__doc__.replace("\n    ", " ")


def test_each_command_takes_its_options_by_their_declared_names():
    """What a command's `load` (or function) takes: every declared option but where the jobs run
    (`declared.EXECUTION`, which goes to `Execution`)."""
    for command in (*declared.JOBS, declared.RUN):
        load = inspect.signature(importlib.import_module(f"biostudy.commands.{command.name}").load).parameters
        wanted = {o.name for o in command.options if o.name not in declared.EXECUTION and o.side != "python"}
        assert wanted <= set(load), (command.name, wanted - set(load))


@pytest.mark.parametrize("args, call, key", [
    (["convergence", "nowhere.toml", "--levels", "1"], lambda: biostudy.convergence("nowhere.toml", levels=1),
     "levels"),
    (["convergence", "nowhere.toml", "--levels", "many"],
     lambda: biostudy.convergence("nowhere.toml", levels="many"), "levels"),
    (["convergence", "nowhere.toml", "--tolerance", "-1"],
     lambda: biostudy.convergence("nowhere.toml", tolerance=-1), "tolerance"),
    (["convergence", "nowhere.toml", "--series", "space,sideways"],
     lambda: biostudy.convergence("nowhere.toml", series="space,sideways"), "series"),
    (["sweep", "nowhere.toml", "--workers", "0"], lambda: biostudy.sweep("nowhere.toml", workers=0), "workers"),
    (["calibrate", "nowhere.toml", "--workers", "-2"], lambda: biostudy.calibrate("nowhere.toml", workers=-2),
     "workers"),
    (["export", "a.nc", "out", "--format", "obj"], lambda: biostudy.export("a.nc", "out", format="obj"), "format"),
    (["plot", "a.nc", "--warp", "big"], lambda: biostudy.plot("a.nc", warp="big"), "warp"),
])
def test_the_same_mistake_gets_the_same_words_from_the_command_line_and_python(args, call, key, tmp_path,
                                                                              monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, args)
    with pytest.raises(BadInput) as caught:
        call()
    assert caught.value.key == key and not caught.value.more
    flag = next(o for c in declared.COMMANDS if c.name == args[0] for o in c.options if o.name == key).flags[-1]
    assert result.exit_code == 2 and result.stderr == f"error: {flag}: {caught.value.problem}\n", result.stderr
    assert not list(tmp_path.iterdir())  # refused before anything was read or written
