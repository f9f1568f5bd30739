"""study.nc's fields copied chunk by chunk from the case files (`study_fill`) and the cases' small variables read
through h5py (`study_cases.Reader`): the values xarray reads from each case file, and the file written when every
field is read and compressed again."""
import shutil

import h5py
import netCDF4
import numpy as np
import pytest
import xarray as xr
from study_files import same_files

from biostudy.commands.sweep import run_study
from biostudy.data import combine, netcdf, netcdf_io, study_cases, study_fill, writing
from biostudy.execution.jobs import Execution
from biostudy.plans.study import load_study

R = [50.0, 60.0, 70.0, 80.0, 90.0]


@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """A finished sweep of five cases of a tiny 2-D scene (16 x 16, 3 outputs): (study file, its directory)."""
    root = tmp_path_factory.mktemp("fill")
    from conftest import TINY_SCENE

    (root / "tiny.toml").write_text(TINY_SCENE)
    (root / "study.toml").write_text(f'scene = "tiny.toml"\n[sweep]\nmode = "grid"\ng = [1e8]\nr = {R}\n')
    run_study(load_study(root / "study.toml"), root / "out", Execution())
    return root / "study.toml", root / "out"


def _case(out, r):
    return out / "cases" / f"g=1e+08_r={r:g}.nc"


def _written_before(path, fill_value=None):
    """The case file as a sweep before issue 11 wrote it (no study dimensions, steps_bisections); `fill_value`:
    phi stored with that _FillValue and one NaN, c in one chunk per case (neither copyable as it is)."""
    with xr.open_dataset(path) as ds:
        run = study_cases.as_run(ds.load(), {}).rename(steps_bisected="steps_bisections")
    run.attrs.pop(netcdf.CASE_DIMENSIONS)
    encoding = netcdf.encoding(run)
    if fill_value is not None:
        run["phi"][1, 2, 3] = np.nan
        encoding["phi"]["_FillValue"] = fill_value
        encoding["c"]["chunksizes"] = run["c"].shape
    path.unlink()
    netcdf_io.write(run, path, encoding)


@pytest.fixture
def varied(swept, tmp_path):
    """The sweep's cases, varied: r=50 and 60 as written, 70 as written before issue 11, 80 too with phi's fill
    value -1 (and a NaN) and c in one chunk, 90 missing: (plan, directory)."""
    study, out = swept
    shutil.copytree(out / "cases", tmp_path / "cases")
    _written_before(_case(tmp_path, 70.0))
    _written_before(_case(tmp_path, 80.0), fill_value=-1.0)
    _case(tmp_path, 90.0).unlink()
    return load_study(study), tmp_path


def test_copied_chunks_hold_the_fields_xarray_reads_and_the_file_made_by_compressing_again(varied, monkeypatch):
    plan, out = varied
    copied = []
    copy = study_fill.copy_chunks
    monkeypatch.setattr(study_fill, "copy_chunks", lambda source, target, at: copied.append(
        (at, source.name.strip("/"))) or copy(source, target, at))
    fast = combine.write_study(plan, out).rename(out / "copied.nc")
    fields = ("phi", "c", "alpha")
    assert sorted(copied) == sorted([((0, i), f) for i in (0, 1, 2) for f in fields] + [((0, 3), "alpha")])
    study = xr.load_dataset(fast)
    for r in R[:4]:
        with xr.open_dataset(_case(out, r)) as ds:
            case = netcdf.renamed(ds).load()
        here = study.sel(g=1e8, r=r)
        for name in (*fields, "phi_mean", "c_mean", "steps_bisected", "time", "x"):
            expected = case[name].squeeze(("g", "r"), drop=True) if "r" in case[name].dims else case[name]
            np.testing.assert_array_equal(here[name].values, expected.values.astype(here[name].dtype), err_msg=name)
    phi = study.phi.sel(g=1e8)
    assert np.isnan(phi.sel(r=80.0).values[1, 2, 3]) and (phi.sel(r=80.0).values != -1).all()
    assert np.isnan(phi.sel(r=90.0).values).all() and study.status.sel(g=1e8, r=90.0).item() == "missing"
    # every field read and compressed again: the same file, variable by variable (values bit for bit)
    monkeypatch.setattr(study_fill, "copyable", lambda *args: False)
    slow = combine.write_study(plan, out).rename(out / "compressed.nc")
    same_files(fast, slow)


def test_small_variables_read_through_h5py_are_netcdf4s_as_stored(swept):
    """The fast path of `Reader` (h5py, as stored) against netCDF4's reading of every small variable and
    coordinate, scalars (mu) and arrays (x_bounds), fill values NaN where a run wrote none."""
    study, out = swept
    plan = load_study(study)
    dims, coords = combine._study_coordinates(plan)
    reader = study_cases.Reader(coords)
    cases = [reader.read(_case(out, r), plan.scenes[f"g=1e+08_r={r:g}"].substratum_attrs()) for r in R]
    assert cases[0].values is None and all(case.values is not None for case in cases[1:])
    assert {"mu", "x_bounds", "phi_mean", "steps_bisected", "time"} <= set(cases[1].values)
    for r, case in zip(R[1:], cases[1:]):
        with netCDF4.Dataset(_case(out, r)) as nc:
            for name, values in case.values.items():
                stored = nc.variables[name]
                stored.set_auto_maskandscale(False)
                expected = np.asarray(stored[...]).reshape(values.shape)
                assert values.dtype == expected.dtype and values.tobytes() == expected.tobytes(), name


def test_a_damaged_chunk_stops_the_write_as_before(varied):
    """A case file whose compressed field is damaged (bytes inside a chunk changed) fails study.nc's write,
    naming it, and leaves no study.nc: the chunk's zlib stream fails before it is copied, and the
    field read instead fails its checksum."""
    plan, out = varied
    path = _case(out, 60.0)
    with h5py.File(path, "r") as file:
        info = file["phi"].id.get_chunk_info(1)
    with open(path, "r+b") as handle:
        handle.seek(info.byte_offset + info.size // 2)
        byte = handle.read(1)
        handle.seek(info.byte_offset + info.size // 2)
        handle.write(bytes([byte[0] ^ 0xFF]))
    with pytest.raises(writing.NotWritten, match="study.nc"):
        combine.write_study(plan, out)
    assert not (out / "study.nc").exists() and not list(out.glob(".study.nc.*"))
