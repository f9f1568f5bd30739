"""What a signal does to a command and to a sweep's workers (issue 25 item 18, issue 27 item 4).

SIGTERM exits 143 and Ctrl-C (SIGINT) 130, after the same unwinding (nothing half-written: the writes
themselves are tested by `test_faults_hostile.py`, section 4); nothing but those two is ever "interrupted".
The fork server that starts a sweep's workers killed from outside (as `kill -9` of every child of a sweep
does) costs no case: a worker it was starting is started afresh, a worker it had started computes on.
"""
from __future__ import annotations

import os
import signal
from multiprocessing import forkserver

import numpy as np
import psutil
import pytest
import xarray as xr
from test_sweep import _wait_for as wait_for
from typer.testing import CliRunner

import solver
from biostudy.cli import app
from biostudy.commands import sweep
from biostudy.data.finish import Record
from biostudy.execution import pool, worker

cli = CliRunner()


@pytest.mark.parametrize("sent, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_sigterm_exits_143_and_ctrl_c_130(tiny_study, tmp_path, monkeypatch, sent, status):
    def signalled(*args, **kwargs):
        signal.raise_signal(sent)

    monkeypatch.setattr(sweep, "run_study", signalled)
    result = cli.invoke(app, ["sweep", str(tiny_study), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code == status, result.output
    assert result.stderr.strip() == "interrupted: finished files are kept, nothing is left half-written"


def test_an_eof_error_is_not_an_interruption(tiny_study, tmp_path, monkeypatch):
    def lost(*args, **kwargs):  # as a fork server killed while it started a worker made one (issue 25, item 18)
        raise EOFError("unexpected EOF")

    monkeypatch.setattr(sweep, "run_study", lost)
    result = cli.invoke(app, ["sweep", str(tiny_study), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code not in (130, 143) and "interrupted" not in result.output, result.output
    assert isinstance(result.exception, EOFError)


def _tiny_problem() -> solver.Problem:
    grid = solver.Grid((8, 8), 1.0)
    x, y = grid.cell_coordinates()
    phi0 = (((x - 4) ** 2 + (y - 4) ** 2) <= 4).astype(float)
    return solver.Problem(grid=grid, phi0=phi0, nutrient_held=(x > 7) & (y > 7), t_end=0.01, steps=2,
                          output_times=[0, 0.01], name="tiny")


def _tiny_task(path=None) -> worker.Task:
    """The tiny problem as a worker's task: its case file at `path` (None: its bytes come back)."""
    return worker.Task(_tiny_problem(), Record("", "", ""), None if path is None else str(path))


def _fork_server() -> int:
    return forkserver._forkserver._forkserver_pid


@pytest.mark.slow
def test_a_fork_server_killed_while_it_starts_a_worker_costs_no_case(monkeypatch):
    pool.warm_up()
    workers = pool.LocalPool(1)
    server = _fork_server()
    os.kill(server, signal.SIGSTOP)  # the request to start a worker waits in its queue, unanswered
    read_signed = forkserver.read_signed

    def killed_first(fd):  # the pool waits for the new worker's pid: the fork server dies instead
        monkeypatch.setattr(forkserver, "read_signed", read_signed)
        os.kill(server, signal.SIGKILL)
        return read_signed(fd)

    monkeypatch.setattr(forkserver, "read_signed", killed_first)
    try:
        workers.submit("a", _tiny_task())
        [(case, outcome)] = workers.finished()
    finally:
        workers.close(False)
    assert (case, outcome.status) == ("a", "done"), outcome.message


@pytest.mark.slow
def test_a_fork_server_killed_while_its_worker_computes_costs_no_case(tmp_path):
    pool.warm_up()
    workers = pool.LocalPool(1)
    try:
        workers.submit("a", _tiny_task())
        assert [c for c, o in workers.finished()] == ["a"]  # a worker is there, idle
        server = psutil.Process(_fork_server())
        server.kill()
        wait_for(lambda: server.status() == psutil.STATUS_ZOMBIE, 60)  # dead; multiprocessing reaps it
        workers.submit("b", _tiny_task(tmp_path / "b.nc"))  # the worker the dead server started computes on
        [(case, outcome)] = workers.finished()
        assert (case, outcome.status, outcome.written) == ("b", "done", True), outcome.message
        assert np.isfinite(xr.load_dataset(tmp_path / "b.nc").phi.values).all()
    finally:
        workers.close(False)



def test_an_error_while_an_interruption_unwinds_is_still_the_interruption(tiny_study, tmp_path, monkeypatch):
    def cleanup_fails(*args, **kwargs):  # as closing a file whose write SIGTERM cut short can fail in HDF5
        try:
            signal.raise_signal(signal.SIGTERM)
        finally:
            raise RuntimeError("NetCDF: HDF error")

    monkeypatch.setattr(sweep, "run_study", cleanup_fails)
    result = cli.invoke(app, ["sweep", str(tiny_study), "-o", str(tmp_path / "out"), "-q"])
    assert result.exit_code == 143, result.output
    assert result.stderr.strip() == "interrupted: finished files are kept, nothing is left half-written"


@pytest.mark.slow
def test_a_sigterm_to_every_process_of_a_job_fails_no_case():
    """A batch system's SIGTERM reaches the workers too, maybe before the sweep's own process: a worker computes on
    (the sweep's process, interrupted, ends it), so no case is recorded as failed for it."""
    pool.warm_up()
    workers = pool.LocalPool(1)
    try:
        workers.submit("a", _tiny_task())
        assert [o.status for c, o in workers.finished()] == ["done"]  # the worker has started
        workers.submit("b", _tiny_task())
        workers.workers[0].process.terminate()  # SIGTERM
        [(case, outcome)] = workers.finished()
        assert (case, outcome.status) == ("b", "done"), outcome.message
    finally:
        workers.close(False)
    assert all(w.process.exitcode is not None for w in workers.workers)  # ended all the same
