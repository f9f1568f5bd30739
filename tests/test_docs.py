"""Docs that cannot drift: the README's measured numbers come from their generated tables, and its key lists
from the code (as `test_registry.py` does for the parameters)."""
import importlib.util
import re
from pathlib import Path

import click
import typer.main

from biostudy.cli import app
from biostudy.inputs.keys import all_keys, field_of
from biostudy.inputs.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def ticked_words(text: str) -> set[str]:
    """Every word inside `backticks`, line by line (a table's escaped bars stay inside their line)."""
    words = set()
    for line in text.splitlines():
        for span in re.findall(r"`([^`]+)`", line):
            words |= set(re.findall(r"[A-Za-z_][A-Za-z_0-9-]*", span))
    return words


def test_the_generated_blocks_agree_with_their_tables():
    spec = importlib.util.spec_from_file_location("docs_sync", ROOT / "scripts" / "docs_sync.py")
    docs_sync = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docs_sync)
    found = set()
    for page in docs_sync.PAGES:
        text = page.read_text(encoding="utf-8")
        _, changed = docs_sync.synced(text)
        assert not changed, f"{page.name}: blocks {changed} disagree with their tables: run python scripts/docs_sync.py"
        found |= set(re.findall(r"<!-- generated: ([\w-]+) -->", text))
    assert set(docs_sync.BLOCKS) <= found


def test_every_scene_key_is_in_the_readme_and_every_key_it_names_exists():
    missing = sorted(set(all_keys(Scene)) - ticked_words(README))
    assert not missing, f"scene keys the README does not mention: {missing}"
    for line in README.splitlines():
        for section, key in re.findall(r"`\[(\w+)\] (\w+)", line):
            assert field_of(Scene, f"{section}.{key}") is not None, f"README names [{section}] {key}: no such key"


def test_every_command_and_option_is_in_the_readme():
    group = typer.main.get_command(app)
    words = ticked_words(README)
    for name, command in group.commands.items():
        assert f"biostudy {name}" in README, f"the README does not show the command {name}"
        for param in command.params:
            if isinstance(param, click.Option):
                long = [o for o in param.opts if o.startswith("--")]
                assert long and long[0].lstrip("-") in words, f"biostudy {name} {long}: not in the README"
