"""study.nc made two ways from the same case files, and two netCDF files compared variable by variable."""
import numpy as np

from biostudy.data import combine, study_arrays


def same_files(a, b):
    """Two netCDF files hold the same variables, values (bit for bit), types, attributes, chunks and filters, and
    the same global attributes but when and how they were made."""
    import netCDF4

    def attrs(item, leave_out=()):
        return {k: np.asarray(item.getncattr(k)) for k in item.ncattrs() if k not in leave_out}

    def equal(x, y):
        return x.dtype == y.dtype and x.shape == y.shape and (
            x.tobytes() == y.tobytes() if x.dtype.kind != "O" else x.tolist() == y.tolist())

    with netCDF4.Dataset(a) as x, netCDF4.Dataset(b) as y:
        ax, ay = attrs(x, ("created", "history")), attrs(y, ("created", "history"))
        assert list(ax) == list(ay) and all(equal(ax[k], ay[k]) for k in ax)
        assert list(x.variables) == list(y.variables) and list(x.dimensions) == list(y.dimensions)
        for name, u in x.variables.items():
            v = y.variables[name]
            u.set_auto_maskandscale(False)
            v.set_auto_maskandscale(False)
            assert (u.dimensions, u.dtype, u.chunking()) == (v.dimensions, v.dtype, v.chunking()), name
            assert u.chunking() == "contiguous" or u.filters() == v.filters(), name
            au, av = attrs(u), attrs(v)
            assert list(au) == list(av) and all(equal(au[k], av[k]) for k in au), name
            assert equal(np.asarray(u[...]), np.asarray(v[...])), name


def both_ways(plan, out, monkeypatch):
    """study.nc of `plan`'s case files in `out` made with study-wide arrays (`study_arrays`) and with a dataset per
    case (`combine._stacked`, as before them): the two files' paths."""
    arrays = combine.write_study(plan, out).rename(out / "study-arrays.nc")
    declined = []  # the study-wide arrays asked for and declined: the other way was taken
    with monkeypatch.context() as patched:
        patched.setattr(study_arrays, "stacked", lambda *args: declined.append(True))
        datasets = combine.write_study(plan, out).rename(out / "study-datasets.nc")
    assert declined
    return arrays, datasets
