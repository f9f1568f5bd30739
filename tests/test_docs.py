"""Docs that cannot drift: the README's measured numbers come from their generated tables, and its key lists
from the code (as `test_registry.py` does for the parameters)."""
import importlib.util
import re
from pathlib import Path

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


OWN = ("--quiet", "--verbose", "--json", "--help")  # the command line's own: the README's row of them says which


def test_every_command_and_option_is_in_the_readme():
    """Each command's rows of the README's command table (those whose first cell is `biostudy NAME ...`) name
    every one of its options; the command line's own (-q, -v, --json) are in their row."""
    group = typer.main.get_command(app)
    rows = [line.split(" | ")[0] for line in README.splitlines() if line.startswith("| `biostudy ")]
    own = next(line for line in README.splitlines() if line.startswith("| `--json`"))
    for name, command in group.commands.items():
        mine = " ".join(row for row in rows if row.startswith(f"| `biostudy {name} ") or row == f"| `biostudy {name}`")
        assert mine, f"the README's command table has no row of biostudy {name}"
        for param in command.params:
            if param.param_type_name == "option":  # not isinstance: typer may bring its own click
                long = [o for o in param.opts if o.startswith("--")]
                assert long, (name, param.opts)
                where = own if long[0] in OWN else mine
                assert any(re.search(rf"(?<![\w-]){re.escape(o)}(?![\w-])", where) for o in param.opts), \
                    f"biostudy {name} {long[0]}: not in its row of the README's command table"
                if long[0] == "--json":
                    assert f"`{name}`" in own, f"the README's row of --json does not name {name}"


# A pointer to a section: README or docs/PAGE.md, then the section's title in quotes ("docs/clusters.md, 'Dask
# inside an allocation'", "docs/model.md (\"The dataset\")", "README: 'Set up'"); it resolves when a heading of that
# page holds the title (a heading may say more: "Memory (issue 29.2) and how far one machine goes").
POINTER = re.compile(r"(README(?:\.md)?|docs/[\w/.-]+?\.md)`?(?:[,:]\s*|\s*\(\s*|\s+)(?:section\s+)?"
                     r"(?:\"([^\"]{2,120})\"|'([^']{2,120})'|“([^”]{2,120})”)")


def _titles(page: Path) -> set[str]:
    """The section titles of a Markdown page, as pointers spell them (no #, no backticks, any case)."""
    lines = page.read_text(encoding="utf-8").splitlines()
    return {line.lstrip("#").replace("`", "").strip().casefold() for line in lines if re.match(r"#{1,6} ", line)}


def _texts(path: Path) -> list[str]:
    """What a file says to a reader: a Python file's strings (help, messages, docstrings) and comments, a page's
    text, a notebook's cells; whitespace collapsed, so a pointer broken over lines reads whole."""
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".ipynb":
        import json

        found = ["".join(cell["source"]) for cell in json.loads(text)["cells"]]
    elif path.suffix == ".py":
        import ast
        import io
        import tokenize

        tree = ast.parse(text)
        found = [node.value for node in ast.walk(tree)
                 if isinstance(node, ast.Constant) and isinstance(node.value, str)]
        found += ["".join(part.value for part in node.values if isinstance(part, ast.Constant))
                  for node in ast.walk(tree) if isinstance(node, ast.JoinedStr)]
        found += [token.string for token in tokenize.generate_tokens(io.StringIO(text).readline)
                  if token.type == tokenize.COMMENT]
    else:
        found = [text]
    return [" ".join(t.split()) for t in found]


def pointers(text: str) -> list[tuple[str, str]]:
    """(page, section title) of every pointer in `text`."""
    return [(page if page.startswith("docs/") else "README.md", next(t for t in titles if t))
            for page, *titles in POINTER.findall(text)]


PLACEHOLDER = re.compile(r"[*]|[/_](x|X|NAME|PAGE)\.")  # tests/test_x.py, docs/PAGE.md: a kind of file, not one
FILE = re.compile(r"\b((?:docs|tests|benchmarks|scripts)/[\w/.-]*\w\.(?:md|py|ipynb))")  # a file of the repository


def test_every_pointer_to_a_section_of_the_readme_or_the_docs_resolves():
    """Code, help texts, messages, tests, the README, the guides and the notebook name sections that exist, and
    files of the repository (a guide, a test, a benchmark) that exist."""
    files = [p for folder in ("biostudy", "solver", "scripts", "benchmarks", "tests")
             for p in (ROOT / folder).rglob("*.py")]
    files += [ROOT / "README.md", *(ROOT / "docs").rglob("*.md"), *(ROOT / "docs").rglob("*.ipynb")]
    broken, seen = [], 0
    for path in files:
        for text in _texts(path):
            broken += [f"{path.relative_to(ROOT)}: {name}: no such file" for name in FILE.findall(text)
                       if not (ROOT / name).exists() and not PLACEHOLDER.search(name)]
            for page, title in pointers(text):
                seen += 1
                target = ROOT / page
                wanted = re.compile(rf"(^|\W){re.escape(title.casefold().strip())}(\W|$)")
                if not target.is_file() or not any(wanted.search(heading) for heading in _titles(target)):
                    broken.append(f"{path.relative_to(ROOT)}: {page}, {title!r}")
    for page in [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]:  # a title leads to one section
        headings = [line for line in page.read_text(encoding="utf-8").splitlines() if re.match(r"#{1,6} ", line)]
        broken += [f"{page.relative_to(ROOT)}: {line!r} twice" for line in set(headings) if headings.count(line) > 1]
    assert seen > 20 and not broken, "\n".join(dict.fromkeys(broken))


def test_a_pointer_is_found_wherever_it_is_written():
    """The check above on made-up input: it must be able to fail."""
    assert pointers("(docs/clusters.md, 'Dask inside an allocation')") == [("docs/clusters.md",
                                                                           "Dask inside an allocation")]
    assert pointers('`docs/model.md` ("The dataset") and README, "Set up"') == [("docs/model.md", "The dataset"),
                                                                               ("README.md", "Set up")]
    gone = "README" + ": 'Sweeps on a Dask cluster'"  # split: the check above reads this file's strings too
    assert pointers(gone) == [("README.md", "Sweeps on a Dask cluster")]
    assert "sweeps on a dask cluster" not in _titles(ROOT / "README.md")
