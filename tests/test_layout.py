"""The layout's promise: imports run one way, stage by stage, with no cycles (function-level imports included)."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# bottom to top: a module may import its own stage and the stages below it, never one above
STAGES = ["solver", "biostudy.formatting", "biostudy.errors", "biostudy.fitting", "biostudy.inputs",
          "biostudy.quantities", "biostudy.data",
          "biostudy.plans", "biostudy.execution", "biostudy.reports", "biostudy.plots", "biostudy.calibration",
          "biostudy.commands",
          "biostudy.cli", "biostudy"]


def modules() -> dict[str, Path]:
    found = {}
    for package in ("solver", "biostudy"):
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            found[name.removesuffix(".__init__")] = path
    return found


def _type_checking(node: ast.If) -> bool:
    return isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The project modules `name` imports anywhere in its file (but under `if TYPE_CHECKING:`)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skipped = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If) and _type_checking(node)
               for n in ast.walk(node)}
    found = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[:len(parts) - node.level + 1] + ([node.module] if node.module else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base for alias in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def stage(name: str) -> int:
    """The stage of a module: that of the longest stage prefix it has."""
    matching = [prefix for prefix in STAGES if name == prefix or name.startswith(prefix + ".")]
    return STAGES.index(max(matching, key=len))


def graph() -> dict[str, set[str]]:
    found = modules()
    return {name: imports(name, path, set(found)) for name, path in found.items()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in edges:
        if v not in index:
            visit(v)
    return found


def test_no_import_cycles():
    found = cycles(graph())
    assert not found, f"import cycles: {found}"


def test_imports_run_one_way_through_the_stages():
    wrong = [f"{a} -> {b}" for a, targets in graph().items() for b in targets
             if stage(b) > stage(a) and not (a == "biostudy" or a.startswith("biostudy.__"))]
    assert not wrong, "imports that run up the stages: " + "; ".join(sorted(wrong))


def test_the_check_sees_a_cycle_and_an_upward_import(tmp_path):
    """The checks above on made-up input: they must be able to fail."""
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
    assert stage("biostudy.plans.study") > stage("biostudy.inputs.scene") > stage("solver.problem")
    assert stage("biostudy.cli.app") > stage("biostudy.commands.run")
    known = {"biostudy.inputs.a", "biostudy.inputs.b"}
    source = tmp_path / "a.py"
    source.write_text("from . import b\nfrom ..plans import study\n")
    assert imports("biostudy.inputs.a", source, known | {"biostudy.plans.study"}) == {"biostudy.inputs.b",
                                                                                      "biostudy.plans.study"}


def test_a_fitting_method_is_asked_for_its_name_only_in_its_declaration():
    """A fitting method is declared once (`calibration.methods`): the rest of biostudy asks the declaration what
    the method needs and makes, never compares its name (issue 38.1)."""
    from biostudy.calibration.methods import METHODS

    found = [f"{path.relative_to(ROOT)}:{node.lineno} {node.value!r}" for name, path in modules().items()
             if name.startswith("biostudy") and name != "biostudy.calibration.methods"
             for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
             if isinstance(node, ast.Constant) and node.value in METHODS]
    assert not found, found
