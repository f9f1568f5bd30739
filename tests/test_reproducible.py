"""A simulation gives the same bits wherever it runs (issue 26: one posterior per file and seed).

A calibration's simulations run in this process (the machine's BLAS threads) or in workers (one thread each):
before, the initial nutrient solve used as many BLAS threads as were allowed, and the agar scene's fields
differed by ~1e-14 between one and two threads, enough to send a surrogate's fit elsewhere.  Every part of a
run now uses one BLAS thread.
"""
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

import solver
from biostudy.inputs.scene import load_scene

AGAR = Path(__file__).resolve().parents[1] / "studies" / "agar2d.toml"


def test_fields_are_bit_identical_with_one_or_two_blas_threads():
    scene = load_scene(AGAR, ["grid.shape=[20,40]", "time.t_end=0.04", "time.steps=10",
                              'numerics.growth_velocity="front"', "g=1.3e8", "r=120.0"])
    runs = []
    for threads in (1, 2):
        with threadpool_limits(limits=threads, user_api="blas"):
            runs.append(solver.simulate(scene.problem()))
    for name in ("phi", "c", "alpha"):
        assert np.array_equal(runs[0][name].values, runs[1][name].values, equal_nan=True), name
