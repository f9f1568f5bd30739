"""The parameter registry: a parameter declared once on `solver.Parameters` reaches the scene schema,
the dataset's attributes, `biostudy show` and the stability and sweep tables, with no other edit."""
import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

from biostudy.formatting import number, units_text
from solver import Parameters
from solver.problem import parameter_infos

# Run in a fresh interpreter: the registry grows by one parameter *before* biostudy is imported, as it
# would if `q` had been written into solver/problem.py.
GROWN = textwrap.dedent("""\
    import dataclasses, json, sys
    import numpy as np
    import solver, solver.problem as problem

    @dataclasses.dataclass(frozen=True)
    class Grown(problem.Parameters):
        q: float = problem.parameter(2.5, "1/T*", "test rate q", ge=0)

    problem.Parameters = solver.Parameters = Grown

    from typer.testing import CliRunner
    import xarray as xr
    from biostudy.cli import app
    from biostudy.execution.jobs import plan_jobs
    from biostudy.plans import catalogue
    from biostudy.reports import stability
    from biostudy.data.combine import _coordinate
    from biostudy.inputs.scene import Scene

    scene, catalogue_file = sys.argv[1], sys.argv[2]
    cli = CliRunner()
    found = {"schema": Scene.model_json_schema()["$defs"]["Params"]["properties"]["q"]}
    bad = cli.invoke(app, ["run", scene, "--set", "params.q=-1", "-o", "bad.nc"])
    found["bad"] = [bad.exit_code, bad.stderr]
    ran = cli.invoke(app, ["run", scene, "--set", "q=3.0", "-o", "run.nc", "-q"])
    found["run"] = [ran.exit_code, ran.output]
    found["attrs_q"] = float(xr.open_dataset("run.nc").attrs["q"])
    found["variable_q"] = [xr.open_dataset("run.nc")["q"].item(), dict(xr.open_dataset("run.nc")["q"].attrs)]
    found["show"] = cli.invoke(app, ["show", "run.nc"]).stdout
    plan = catalogue.load(stability.Path(catalogue_file))
    table = stability.verdicts(plan_jobs(plan), stability.Path("unrun"))
    found["stability_q"] = [table.q.values.tolist(), dict(table.q.attrs)]
    found["sweep_coordinate"] = _coordinate("q", [1.0, 2.0])[1]
    print(json.dumps(found))
    """)


def test_every_declared_parameter_has_units_meaning_default_and_range():
    infos = parameter_infos()
    assert [p.name for p in infos] == ["mu", "nu", "d", "beta", "k_alpha", "k", "g", "r"]
    assert all(p.units and p.long_name and p.bounds for p in infos)
    assert Parameters() == Parameters(**{p.name: p.default for p in infos})


def test_a_parameter_added_to_the_registry_reaches_schema_dataset_show_and_tables(tiny_scene, write_toml, tmp_path):
    catalogue = write_toml("cat.toml", """\
        scene = "tiny.toml"
        [[case]]
        name = "slow q"
        set = { q = 0.5 }
        [[case]]
        name = "default q"
        """)
    done = subprocess.run([sys.executable, "-c", GROWN, str(tiny_scene), str(catalogue)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout.splitlines()[-1])
    schema = found["schema"]
    assert schema["units"] == "1/T*" and schema["default"] == 2.5 and schema["minimum"] == 0
    assert "test rate q" in schema["description"]
    assert found["bad"][0] == 2 and "params.q: must be >= 0 (got -1)" in found["bad"][1]
    assert found["run"][0] == 0, found["run"][1]
    assert found["attrs_q"] == 3.0
    assert found["variable_q"] == [3.0, {"units": "1", "long_name": "test rate q [1/T*]"}]
    assert "q = 3 1/T*" in found["show"], found["show"]
    # datasets write udunits units (T* is dimensionless) and keep the model's in the long name
    assert found["stability_q"] == [[0.5, 2.5], {"units": "1", "long_name": "test rate q [1/T*]"}]
    assert found["sweep_coordinate"]["units"] == "1" and "test rate q" in found["sweep_coordinate"]["long_name"]
    assert "1/T*" in found["sweep_coordinate"]["long_name"]


def test_the_parameters_table_of_docs_model_md_is_the_registry():
    """docs/model.md lists every declared parameter with its meaning, units, default and range."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "model.md").read_text(encoding="utf-8")
    rows = {}
    for line in text.splitlines():
        match = re.match(r"^\| `(\w+)` \| (.+?) \| (.+?) \| (.+?) \| (.+?) \|$", line)
        if match:
            rows[match.group(1)] = match.groups()[1:]
    signs = {"gt": ">", "ge": ">=", "lt": "<", "le": "<="}
    expected = {p.name: (p.long_name, units_text(p.units) or "1", number(p.default, 6),
                         ", ".join(f"{signs[k]} {number(v, 6)}" for k, v in p.bounds.items()))
                for p in parameter_infos()}
    assert rows == expected
