"""PEtab's identifiers and simulation table in a calibration's outputs (issue 26, item 6): `datasetId`,
`replicateId` and `datapointId` reach calibration.nc, calibration.md and the fit's picture; simulation.tsv is
PEtab's simulation table of the model at the estimate, read back by pandas; a simulation.tsv biostudy cannot prove
it wrote (its sha256 not the one calibration.nc records) keeps its bytes.  The fits are analytic models in place
of the solver (`test_calibration_hostile.fitted`), but for the command's ownership, which runs the 8 x 8 colony.
"""
from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from test_calibration_hostile import COST, SCENE, calibration, invoke, one_line
from unit_readers import assert_every_unit_read_alike

from biostudy.formatting import number

HEADER = "observableId\ttime\tmeasurement\tnoiseParameters\tdatasetId\treplicateId\tdatapointId\n"
ROWS = [("biomass", 3.0, 0.52, 0.1, "day1", "A", "p1"),  # time in min; t_ref = 1 h: T* = 0.05
        ("biomass", 3.0, 0.47, 0.1, "day1", "B", "p2"),
        ("biomass", 4.8, 0.81, 0.2, "day2", "A", "p3"),  # T* = 0.08
        ("biomass", 4.8, 0.77, 0.2, "day2", "", "p4")]
SHAPE = np.array([1.0, 1.0, 1.6, 1.6])  # the analytic model: r / 100 x SHAPE per row


def model(values: dict) -> np.ndarray:
    return values["r"] / 100 * SHAPE


def fit(folder: Path, text: str):
    """calibration.nc's dataset of an analytic fit of r to the table `text` (times in min, t_ref = 1 h), as
    `test_calibration_hostile.fitted` makes it."""
    from biostudy.calibration.methods import chosen
    from biostudy.calibration.problem import load_calibration
    from biostudy.calibration.report import dataset
    from biostudy.fitting.objective import Objective

    (folder / "speck.toml").write_text(SCENE)
    (folder / "t.tsv").write_text(text)
    (folder / "c.toml").write_text('scene = "speck.toml"\n[data]\nmeasurements = "t.tsv"\ntime_unit = "min"\n'
                                   't_ref = "1 h"\n[estimate]\nr = [20.0, 250.0]\n[method]\nstarts = 1\n'
                                   'profiles = false\n')
    plan = load_calibration(folder / "c.toml")
    data = np.array([m.value for m in plan.measurements])
    sigma = np.array([m.sigma for m in plan.measurements])

    def evaluate(points):
        return [(model(plan.values(p)) - data) / sigma for p in points]

    result = chosen(plan.spec.method)(Objective(evaluate, len(data), np.full(len(data), 1e-9), ("r",)))
    return dataset(plan, result, model(plan.values(result.estimate.best.x)), COST, {}, {})


def table(header: str = HEADER, rows=ROWS) -> str:
    return header + "".join("\t".join(map(str, row)) + "\n" for row in rows)


def test_dataset_and_replicate_ids_reach_calibration_nc_its_table_and_its_picture(tmp_path):
    from biostudy.calibration.pictures import fit_figure
    from biostudy.calibration.report import table_text
    from biostudy.data import writing

    ds = fit(tmp_path, table())
    writing.write_atomic(ds, tmp_path / "calibration.nc")
    with xr.open_dataset(tmp_path / "calibration.nc") as back:
        for name, column, at in (("dataset", "datasetId", 4), ("replicate", "replicateId", 5),
                                 ("datapoint", "datapointId", 6)):
            assert [str(v) for v in back[name].values] == [row[at] for row in ROWS], name
            assert back[name].attrs["long_name"] == column
        assert back.attrs["measurement_columns"] == HEADER.strip().replace("\t", ", ")

    squares = ((model({"r": float(ds.estimate[0])}) - [row[2] for row in ROWS]) / [row[3] for row in ROWS]) ** 2
    text = table_text(ds)
    assert (f"| day1 | biomass | - | A, B | 2 | {number(squares[:2].sum(), 4)} |\n"
            f"| day2 | biomass | - | A | 2 | {number(squares[2:].sum(), 4)} |\n") in text, text

    ax = fit_figure(ds).axes[0]
    groups = ["measured ± σ, dataset day1, replicate A", "measured ± σ, dataset day1, replicate B",
              "measured ± σ, dataset day2, replicate A", "measured ± σ, dataset day2"]
    assert set(groups) <= {text.get_text() for text in ax.get_legend().texts}
    drawn = {container.get_label(): container.lines[0] for container in ax.containers}  # the error bars' points
    assert [list(drawn[g].get_xdata()) for g in groups] == [[3.0], [3.0], [4.8], [4.8]]
    markers = [drawn[g].get_marker() for g in groups]
    colours = [drawn[g].get_color() for g in groups]
    assert markers[0] != markers[1] and markers[0] == markers[2]  # a marker per replicate: A and B told apart
    assert colours[0] == colours[1] != colours[2] == colours[3]  # a colour per dataset


def test_a_table_without_ids_says_nothing_of_them(tmp_path):
    from biostudy.calibration.pictures import fit_figure
    from biostudy.calibration.report import table_text

    ds = fit(tmp_path, table("observableId\ttime\tmeasurement\tnoiseParameters\n", [row[:4] for row in ROWS]))
    assert set(ds["dataset"].values) == set(ds["replicate"].values) == {""}
    assert "datasetId" not in table_text(ds) and "dataset" not in table_text(ds)
    labels = [t.get_text() for t in fit_figure(ds).axes[0].get_legend().texts]
    assert "measured ± σ" in labels and not any("dataset" in label or "replicate" in label for label in labels)


@pytest.mark.parametrize("header, columns", [
    ("time\tobservableId\tmeasurement\tnoiseParameters\tobservableParameters\tdatasetId\treplicateId\tdatapointId\t"
     "preequilibrationConditionId\tsimulationConditionId\n",
     ["observableId", "preequilibrationConditionId", "simulationConditionId", "time", "simulation",
      "observableParameters", "noiseParameters", "datasetId", "replicateId", "datapointId"]),
    ("observableId\ttime\tmeasurement\tnoiseParameters\n",
     ["observableId", "simulationConditionId", "time", "simulation", "noiseParameters"]),
], ids=["every column", "the required ones"])
def test_the_simulation_table_is_petabs_with_the_model_at_the_estimate(tmp_path, header, columns):
    """PEtab: the measurement table's format with `simulation` for `measurement`, in PEtab's column order; one
    row per measurement; times in the table's own unit (min, not T*)."""
    from biostudy.calibration.petab import simulation_table

    full = "preequilibrationConditionId" in header
    rows = [(row[1], row[0], row[2], row[3], "", *row[4:], "", "") if full else row[:4] for row in ROWS]
    ds = fit(tmp_path, table(header, rows))
    (tmp_path / "simulation.tsv").write_text(simulation_table(ds))
    read = pd.read_csv(tmp_path / "simulation.tsv", sep="\t", keep_default_na=False)
    assert list(read.columns) == columns
    assert len(read) == len(ROWS) and list(read.observableId) == ["biomass"] * len(ROWS)
    expected = model({"r": float(ds.estimate[0])})
    np.testing.assert_array_equal(read.simulation.to_numpy(), ds.fitted.values)
    np.testing.assert_allclose(read.simulation.to_numpy(), expected, rtol=1e-15)
    assert list(read.time) == [row[1] for row in ROWS]  # min, as the table gives them (T* 0.05, 0.08)
    assert list(read.noiseParameters) == [row[3] for row in ROWS]
    assert set(read.simulationConditionId) == {""}
    if full:
        assert list(read.datasetId) == [row[4] for row in ROWS] and list(read.datapointId) == [row[6] for row in ROWS]
        assert list(read.replicateId) == [row[5] for row in ROWS]
        assert set(read.preequilibrationConditionId) == set(read.observableParameters) == {""}


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_biostudys_simulation_table_is_replaced_and_an_edited_one_kept(tmp_path):
    """Its own file (the sha256 calibration.nc records) is replaced, also the one a run stopped between
    writing calibration.nc and simulation.tsv leaves (the one that calibration.nc replaced); the file a user
    edited is the user's.  Written as the umask says."""
    rows = [("biomass", 0.05, 3.1, 0.2, "d1", "A", "p1"), ("biomass", 0.1, 3.6, 0.2, "d1", "A", "p2")]
    path = calibration(tmp_path, table(rows=rows), "[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 1\n"
                       "profiles = false\n")
    out, written = tmp_path / "out", tmp_path / "out" / "simulation.tsv"
    previous = os.umask(0o027)
    try:
        first = invoke("calibrate", path, "-o", out, "-q")
    finally:
        os.umask(previous)
    assert first.exit_code == 0, first.output
    assert stat.S_IMODE(written.stat().st_mode) == 0o640
    with xr.open_dataset(out / "calibration.nc") as ds:
        assert ds.attrs["simulation_tsv_sha256"] == _sha(written)
        fitted = ds.fitted.values
    read = pd.read_csv(written, sep="\t", keep_default_na=False)
    np.testing.assert_array_equal(read.simulation.to_numpy(), fitted)

    old = written.read_bytes()
    (tmp_path / "t.tsv").write_text(table(rows=[(*row[:6], f"q{i}") for i, row in enumerate(rows)]))
    assert invoke("calibrate", path, "-o", out, "-q").exit_code == 0  # the same simulations (reused), new ids
    assert "q0" in written.read_text()
    written.write_bytes(old)  # as a run stopped after calibration.nc and before simulation.tsv leaves it
    again = invoke("calibrate", path, "-o", out, "-q")
    assert again.exit_code == 0, again.output
    assert "q0" in written.read_text()

    with written.open("a") as handle:
        handle.write("biomass\t\t0.2\t4.0\t0.2\td1\tA\tmine\n")
    edited = _sha(written)  # refused before anything runs in a folder biostudy owns too (test_foreign_outputs)
    for force in ([], ["--force"]):
        one_line(invoke("calibrate", path, "-o", out, "-q", *force),
                 "simulation.tsv: exists and is not a file biostudy wrote")
        assert _sha(written) == edited


def test_a_users_simulation_table_that_appears_while_a_calibration_computes_is_not_replaced(tmp_path):
    """The last guard: the writer itself refuses a file whose sha256 the summary does not record (one put there
    after the calibration's check), and replaces one it records."""
    from biostudy.data import claims
    from biostudy.errors import BadInput

    path = tmp_path / "simulation.tsv"
    path.write_text("observableId\tsimulation\nmine\t1\n")
    users = path.read_bytes()
    for attrs in (None, {}, claims.digested("simulation.tsv", "another text\n", "0" * 64)):
        with pytest.raises(BadInput, match="refusing to overwrite"):
            claims.write_digested(path, "observableId\tsimulation\nours\t2\n", attrs, "calibration.nc")
        assert path.read_bytes() == users
    claims.write_digested(path, "ours\n", claims.digested("simulation.tsv", users.decode()), "calibration.nc")
    assert path.read_text() == "ours\n"


def test_calibration_nc_units_read_alike_by_udunits_plain_pint_and_cf_xarray(tmp_path):
    """Issue 36.3: calibration.nc as written (r per T* in um, per hour in um/h, the times in min) quantified by
    pint-xarray with plain pint's registry; UDUNITS and cf_xarray read the same."""
    from biostudy.data import writing

    writing.write_atomic(fit(tmp_path, table()), tmp_path / "calibration.nc")
    with xr.open_dataset(tmp_path / "calibration.nc") as back:
        assert back["estimate_r"].attrs["units"] == "um" and back["estimate_r_real"].attrs["units"] == "um/h"
        assert_every_unit_read_alike(back.load(), "calibration.nc")
