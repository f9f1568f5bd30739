"""Shared fixtures: tiny scene and study files, and tiny runs for the picture and export tests."""
from __future__ import annotations

import os

# Where the test process starts, as the biostudy command does (biostudy.cli): FiPy's scipy solver suite
# before FiPy is first imported, and pictures drawn to files only.
os.environ.setdefault("FIPY_SOLVERS", "scipy")
os.environ["MPLBACKEND"] = "Agg"
# The memory a run may use, fixed for every test and the processes it starts: refusals must not depend on what
# else the machine is doing (a test of a refusal sets its own figure).
os.environ["BIOSTUDY_MEMORY"] = "16 GB"
# One thread per run started through biostudy, in every test process and the processes tests start: the suite's
# two processes fill the two cores (pyproject's -n 2); the tests of threads give their own counts.
os.environ["BIOSTUDY_THREADS"] = "1"

import shutil
import subprocess
import textwrap
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

# One BLAS thread in each test process: the suite's two processes fill the two cores (pyproject's -n 2), and
# OpenBLAS threads spinning on busy cores cost tens of times their work.  Set here, not by OMP_NUM_THREADS
# (numpy is loaded before this file, by plugins), and not in the environment, which the processes tests start
# inherit: the tests of a sweep's workers check that the sweep sets it for them.
ONE_BLAS_THREAD = threadpool_limits(limits=1, user_api="blas")

# A 2-D 16 x 16 scene of 20 steps: ~0.1 s to simulate, yet every part of a scene is there.  Its colony floats (it
# touches no face), so it names the substratum COMSTAT's observables are measured from (calibrations fit them).
TINY_SCENE = """\
name = "tiny"
description = "tiny test scene"

[grid]
shape = [16, 16]
spacing = 1.0

[params]
g = 1e8

[time]
t_end = 0.2
steps = 20
outputs = 3

[[biofilm]]
shape = "sphere"
center = [8.0, 8.0]
radius = 3.0

[[nutrient]]
shape = "box"
lower = [14.0, 14.0]
upper = [16.0, 16.0]

[[obstacle]]
shape = "box"
lower = [0.0, 12.0]
upper = [3.0, 16.0]

[substratum]
face = "y-"
"""

# A 3-D 10 x 9 x 8 scene of 2 µm cells, 10 steps, with a cylindrical obstacle along z.
CUBE_SCENE = """\
name = "cube"
[grid]
shape = [10, 9, 8]
spacing = 2.0
[time]
t_end = 0.1
steps = 10
outputs = 3
[[biofilm]]
shape = "sphere"
center = [10.0, 9.0, 8.0]
radius = 4.0
[[nutrient]]
shape = "box"
lower = [16.0, 14.0, 12.0]
upper = [20.0, 18.0, 16.0]
[[obstacle]]
shape = "cylinder"
center = [4.0, 4.0, 8.0]
radius = 2.0
axis = "z"
"""


@pytest.fixture
def write_toml(tmp_path):
    """write_toml(name, text) -> path of a TOML file in the test's directory (text is dedented)."""

    def write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return write


@pytest.fixture
def tiny_scene(write_toml) -> Path:
    return write_toml("tiny.toml", TINY_SCENE)


@pytest.fixture
def tiny_study(write_toml, tiny_scene) -> Path:
    """A 2 x 2 grid sweep over g and r of the tiny scene."""
    return write_toml("tiny-sweep.toml", """\
        description = "tiny test sweep"
        scene = "tiny.toml"
        [sweep]
        mode = "grid"
        g = [1e8, 1e9]
        r = [50.0, 100.0]
        """)


@pytest.fixture
def slow_study(write_toml, tiny_scene):
    """slow_study(steps, values) -> a study of the tiny scene over r whose cases take seconds each (to be
    interrupted or killed while they run)."""

    def write(steps: int, values=(50.0, 60.0, 70.0, 80.0)) -> Path:
        return write_toml("slow.toml", f"""\
            scene = "tiny.toml"
            [set]
            "time.t_end" = 1.0
            "time.steps" = {steps}
            [sweep]
            r = {list(values)}
            """)

    return write


@pytest.fixture(scope="session")
def tiny_run():
    """tiny_run(shape, spacing=1.0) -> the dataset of a few steps of a blob growing toward a source in the
    far corner cell, with an obstacle block (x, y < 2 cells) in the near corner; for picture and export tests."""
    from solver import Grid, Problem, simulate

    def run(shape, spacing=1.0):
        grid = Grid(shape, spacing)
        coords = grid.cell_coordinates()
        centre = [0.5 * n * spacing for n in shape]
        phi0 = (sum((q - m) ** 2 for q, m in zip(coords, centre)) <= (2 * spacing) ** 2).astype(float)
        held = np.logical_and.reduce([q > (n - 1) * spacing for q, n in zip(coords, shape)])
        blocked = np.logical_and.reduce([q < 2 * spacing for q in coords[:2]])
        return simulate(Problem(grid=grid, phi0=np.where(blocked, 0, phi0), nutrient_held=held,
                                obstacle=blocked, t_end=0.02, steps=4, output_times=[0, 0.01, 0.02], name="tiny"))

    return run


@pytest.fixture(scope="session")
def with_mechanics():
    """with_mechanics(ds, unsolved=None) -> a run's dataset with p (Pa, cells) and u (µm, nodes) added in the
    layout of a run's dataset (on `time_mechanics`), distinct in every entry; output index `unsolved` left out of
    `time_mechanics` (mechanics not solved there)."""

    def add(ds, unsolved=None):
        ds = ds.copy()
        cell_dims = [d for d in ("z", "y", "x") if d in ds.dims]
        solved = [i for i in range(ds.sizes["time"]) if i != unsolved]
        p = (-10.0 * ds["phi"] + ds["x"] * 0.1).isel(time=solved).rename(time="time_mechanics")
        ds["p"] = p.assign_attrs(units="Pa", long_name="hydrostatic stress")
        nodes = {f"{d}_node": np.arange(ds.sizes[d] + 1) * ds.attrs["grid_spacing"] for d in cell_dims}
        shape = (len(solved), *(v.size for v in nodes.values()), len(cell_dims))
        u = np.random.default_rng(1).normal(size=shape)
        ds["u"] = (("time_mechanics", *nodes, "component"), u, {"units": "um", "long_name": "displacement"})
        return ds.assign_coords(nodes).assign_coords(component=list("xyz"[: len(cell_dims)]))

    return add


@pytest.fixture
def drawn(monkeypatch):
    """The figures `biostudy.plots.plot` draws, by file name, kept open so a test can read what is on them
    (images, lines, colour scales, titles); each is still written to its file.  Closed afterwards."""
    import matplotlib.pyplot as plt

    import biostudy.plots as plots

    figures = {}

    def keep(fig, path):
        figures[Path(path).name] = fig
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=20)
        return Path(path)

    monkeypatch.setattr(plots, "save", keep)
    yield figures
    for fig in figures.values():
        plt.close(fig)


def pytest_collection_modifyitems(items):
    """Files that hold `slow` tests first, then the others by their number of tests, largest first: xdist
    (`--dist loadfile --no-loadscope-reorder`, pyproject) hands files out in collection order, so the long ones
    start at once and the quick ones fill the end instead of one long file running alone at the end.  (Without
    --no-loadscope-reorder xdist would reorder the files by their number of tests alone.)"""
    slow, count = set(), Counter(item.path for item in items)
    for item in items:
        if item.get_closest_marker("slow"):
            slow.add(item.path)
    items.sort(key=lambda item: (item.path not in slow, -count[item.path]))  # stable: a file's order is kept


@pytest.fixture
def small_disk(tmp_path):
    """A 2 MB tmpfs; fill() leaves it about full."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode:
        pytest.skip(f"cannot mount a tmpfs here ({mounted.stderr.decode().strip()})")

    def fill():
        with open(disk / "filler", "ab") as handle:
            handle.write(b"\0" * shutil.disk_usage(disk).free)

    try:
        yield disk, fill
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=True)
