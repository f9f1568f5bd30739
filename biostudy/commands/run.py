"""`biostudy run SCENE`: one simulation, its dataset written atomically with what produced it.

The output is checked before anything is computed (`targets.check_run`): never
an input, never a file biostudy did not write; an earlier result of the same
scene is replaced and the message says so.  The dataset carries every
observable (`quantities.observables`) besides the fields, and each key an
override set as a scalar coordinate (`combine.with_overrides`): a run keeps its
shape, and runs of one scene with different ``--set`` values combine along it.
``continue_from`` goes on from a finished run of the same scene
(`data.continuation`): the dataset is then the whole history.  The output is
claimed for this run (`claims.claim`): a second run into the same output is
refused while this one computes, and a file written there meanwhile by anything
else is not replaced; ``with load(...) as loaded:`` gives the claim back however
the block ends.
"""
from __future__ import annotations

import dataclasses
import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import xarray as xr

import solver
from solver.restart import start_state

from ..data import claims, combine, continuation, incomplete, netcdf_io, writing
from ..data.finish import Record, finish
from ..data.spool import Spool
from ..errors import BadInput, Failed
from ..execution.estimate import estimate
from ..execution.targets import check_run, claim_run
from ..execution.worker import provenance, with_threads
from ..inputs import bundled, resources
from ..inputs.keys import apply_overrides, given_by, key_parts, parse_override
from ..inputs.resources import Preflight
from ..inputs.scene import Scene, load_scene, overrides_text, scene_from_data
from ..quantities import alerts, error_bars

log = logging.getLogger(__name__)  # detail for `-v` and for Python callers who configure logging (cli.logs)


@dataclass(frozen=True)
class Loaded:
    """A scene ready to run: where it came from, its overrides and where its dataset goes."""

    path: Path | None  # None: a scene given as data (the Python API)
    scene: Scene
    overrides: tuple[str, ...]
    target: Path | None  # None: the dataset is only returned (the Python API)
    replacing: str  # what the final message adds when the target is replaced ("" if nothing is)
    previous: xr.Dataset | None = None  # the run it continues
    previous_path: Path | None = None
    claim: claims.Claim | None = None  # the output, reserved for this run until `compute` ends
    threads: int | None = None  # the run's threads, instead of the scene's or the processors here
    error_estimate: bool = False  # its companions run too, each observable's Q_error added (`execution.estimate`)

    def __enter__(self) -> Loaded:
        return self

    def __exit__(self, *exc) -> None:
        """The output's claim given back however the block ends: interrupted before `compute` took it over, its
        temporary goes now, not at the process's exit."""
        if self.claim is not None:
            self.claim.release()


@dataclass(frozen=True)
class Result:
    dataset: xr.Dataset
    target: Path | None
    replacing: str

    def warnings(self) -> list[str]:
        """What a user should know about the result besides the summary (`quantities.alerts`): a vanished dense
        biofilm, a biofilm lost; error bars asked for and not made, and why."""
        said = str(self.dataset.attrs.get(error_bars.ATTRIBUTE, ""))
        missing = [f"no error bars: {said.removeprefix('not estimated: ')}"] if said.startswith("not estimated") else []
        return [*alerts.said(self.dataset.attrs), *missing]

    def message(self) -> str:
        attrs = self.dataset.attrs
        went_on = f", continuing {attrs['continued_from'].split(' (')[0]}" if "continued_from" in attrs else ""
        companions = (f", error bars' companions {attrs['error_estimate_wall_time']:.3g} s"
                      if "error_estimate_wall_time" in attrs else "")
        return (f"wrote {self.target} (wall time {attrs['wall_time']:.3g} s, {attrs['steps_taken']} steps, "
                f"{attrs['steps_bisected']} bisected{went_on}{companions}){self.replacing}")


def default_output(scene: Scene, previous: Path | None = None) -> Path:
    """NAME.nc in the current directory, the scene's name made a file name; a continuation of RUN.nc:
    RUN-tT_END.nc beside it (never the run it reads)."""
    if previous is not None:
        return previous.with_name(f"{previous.stem}-t{scene.time.t_end:g}.nc")
    return Path(re.sub(r"[^\w.+-]", "-", scene.name) + ".nc")


def load(scene: str | Path | dict, *, set: tuple[str, ...] | list[str] = (),  # noqa: A002
         output: Path | None = None, force: bool = False, continue_from: str | Path | None = None,
         threads: int | None = None, error_estimate: bool = False, write: bool = True) -> Loaded:
    """Read and validate a scene (a path, a bundled name, or its data as a dict) with its overrides `set`, the
    run it continues, and its output before anything is computed (the options: `declared.RUN`; `threads`: the
    run's, checked there; `write`: the dataset goes to `output` or NAME.nc); bad input is `BadInput`."""
    overrides = set
    preflight = Preflight(runs=True, streamed=write or output is not None)  # a run that writes streams its outputs
    if isinstance(scene, dict):
        data = {"name": "scene", **scene}
        path, loaded = None, scene_from_data(data, "<scene>", given_by(apply_overrides(data, overrides), "--set"),
                                             preflight=preflight)
    else:
        path = bundled.resolve(scene)
        loaded = load_scene(path, overrides, preflight=preflight)
    log.debug("%s: %s cells of %g µm, %d steps to T* = %g, %d outputs, mechanics %s", loaded.name,
              " × ".join(map(str, loaded.grid.shape)), loaded.grid.spacing, loaded.time.steps, loaded.time.t_end,
              loaded.time.count(), "on" if loaded.mechanics is not None and loaded.mechanics.enabled else "off")
    if continue_from is not None and error_estimate:  # its companions would have to repeat the run it continues
        raise BadInput("a continued run has no error bars: its companions would repeat the run it continues from "
                       "T* = 0; run the whole span with --error-estimate instead", None, "--error-estimate")
    previous = None
    if continue_from is not None:
        continue_from = Path(continue_from)
        previous = continuation.previous_run(continue_from, loaded)
    if not write and output is None:
        return Loaded(path, loaded, tuple(overrides), None, "", previous, continue_from, threads=threads,
                      error_estimate=error_estimate)
    try:
        target = Path(output) if output is not None else default_output(loaded, continue_from)
        replacing = check_run(loaded, path, target, force, inputs=[continue_from] if continue_from else [],
                              history=previous.sizes["time"] if previous is not None else None)
        return Loaded(path, loaded, tuple(overrides), target, replacing, previous, continue_from, claim_run(target),
                      threads, error_estimate)
    except BaseException:
        if previous is not None:
            previous.close()  # open, read lazily (`continuation.previous_run`)
        raise


def _first_dataset() -> None:
    """xarray's first dataset with a variable loads its array backends (dask: a second or more): made before
    the steps, so that it is not a cost after the last one that the progress lines' time left (paced on the
    steps) cannot see; the run takes as long."""
    xr.Dataset({"warm": ("warm", [0.0])})


def _simulated(loaded: Loaded, progress, sink: Spool | None = None) -> xr.Dataset:
    """The run's dataset: simulated (from the run it continues, if any), with every observable, stamped; its
    fields go to `sink` as they are made, if given (then they are lazy arrays reading it)."""
    _first_dataset()
    problem = with_threads(loaded.scene.problem(), threads=loaded.threads)
    if loaded.previous is not None:
        problem = dataclasses.replace(problem, **start_state(loaded.previous))
    try:
        ds = solver.simulate(problem, progress=progress, sink=sink)
    except solver.SimulationError as error:
        message = f"simulation failed: {loaded.path or loaded.scene.name}: {error}"
        if error.partial is None:
            raise Failed(message) from None
        why = f"{error.cause}{' at ' + error.where if error.where else ''}"
        raise Stopped(message, _finished(loaded, incomplete.marked(error.partial, why))) from None
    return _finished(loaded, ds)


def _finished(loaded: Loaded, ds: xr.Dataset) -> xr.Dataset:
    """The simulated dataset with its history (a continuation), provenance, observables and warnings."""
    log.debug("%s: wall time %.3g s (%s)", loaded.scene.name, ds.attrs["wall_time"], ", ".join(
        f"{name.removeprefix('wall_time_')} {seconds:.3g} s" for name, seconds in ds.attrs.items()
        if name.startswith("wall_time_")))
    if loaded.previous is not None and loaded.previous_path is not None:
        ds = continuation.continued(loaded.previous, loaded.previous_path, ds)
    pairs = {".".join(key_parts(key)): value for key, value in map(parse_override, loaded.overrides)}
    ds.attrs.update(provenance())  # where it was computed, as a worker's run says (`execution.worker.solve`)
    ds = finish(ds, Record.of(loaded.scene, loaded.path, overrides_text(pairs)))
    if loaded.previous is not None:
        before = ds.attrs.pop("history_before")
        ds.attrs["history"] = f"{before}\n{ds.attrs['history']}" if before else ds.attrs["history"]
    ds = combine.with_overrides(ds, pairs)
    return ds


class Stopped(Exception):
    """A simulation that stopped (`solver.SimulationError`), with the dataset of what it computed up to there."""

    def __init__(self, message: str, dataset: xr.Dataset):
        super().__init__(message)
        self.message, self.dataset = message, dataset


def _write(loaded: Loaded, ds: xr.Dataset) -> None:
    """The dataset to the run's target, atomically (through its claim); `Failed` if it cannot be written."""
    assert loaded.target is not None
    try:
        if loaded.claim is not None:
            loaded.claim.write_dataset(ds)
        else:
            writing.write_atomic(ds, loaded.target)
    except OSError as error:  # e.g. the disk filled up while it ran (`writing.NotWritten`)
        kept = "the earlier file there is kept as it was" if loaded.replacing else "nothing was written"
        raise Failed(f"{error}; this run's result is lost ({kept})") from None


def compute(loaded: Loaded, *, progress: Callable[[solver.Progress], None] | None = None) -> Result:
    """Simulate and write the dataset (stamped with the scene, its file, the overrides and the software);
    a simulation that fails, or a dataset that cannot be written, is `Failed`; the output's claim ends here.
    A run that writes a file streams its fields to a spool beside it (`data.spool`) and returns the file
    written, opened lazily: its memory does not grow with its outputs."""
    spool = None
    try:
        if loaded.target is not None and resources.streams(loaded.scene):
            spool = Spool(loaded.target)  # no file until the first output
        kept = "the earlier file there is kept as it was" if loaded.replacing else "nothing was written"
        try:
            ds = _simulated(loaded, progress, spool)
        except writing.NotWritten as error:  # the spool's disk filled up while it ran
            raise Failed(f"{error}; this run stopped there and its result is lost ({kept})") from None
        except Stopped as stopped:  # what it computed up to there is kept, marked incomplete, but not over a result
            if loaded.target is None:
                raise Failed(stopped.message) from None
            if loaded.replacing:
                raise Failed(f"{stopped.message}; the earlier result at {loaded.target} is kept as it was (this "
                             "run's incomplete outputs are not written over it)") from None
            _write(loaded, stopped.dataset)
            raise Failed(f"{stopped.message}; {incomplete.kept(stopped.dataset, loaded.target)}") from None
        if loaded.error_estimate:  # companions of the whole run (never a continuation: `load`)
            ds = estimate(loaded.scene, loaded.path or "<scene>", ds, log.info, loaded.threads).applied(ds)
        if loaded.target is not None:
            _write(loaded, ds)
            ds = netcdf_io.open_dataset(loaded.target)
        elif loaded.previous is not None:
            ds = ds.load()  # the history it continues, read before that run's file is closed
    finally:
        if loaded.previous is not None:
            loaded.previous.close()
        if spool is not None:
            spool.close()
        if loaded.claim is not None:
            loaded.claim.release()
    return Result(ds, loaded.target, loaded.replacing)
