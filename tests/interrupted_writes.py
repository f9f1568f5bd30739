"""A real SIGTERM (or SIGINT, Ctrl-C) at many points of a dataset's write (run by tests/test_faults_hostile.py
in a process of its own).

    python interrupted_writes.py DIR KIND:TRIALS[:SIGNAL]...

KIND ``run``: ``biostudy run SCENE -o DIR/out.nc`` with the simulation replaced by a dataset made beforehand
(64² cells, 40 outputs), so that writing it is most of what the command does; ``study``: ``biostudy sweep`` of
a study whose cases are finished (two, 24², 10 outputs), so that it reads them back and writes study.nc. This
process imports and prepares once, then forks one child per trial, which runs the command in-process as
`biostudy` does; the parent sends the child SIGNAL (TERM unless given: TERM or INT) after a delay spread
evenly over the time an uninterrupted child takes (a sweep: over its second half, where it writes), and waits
at most HANG seconds for it to end (then kills it: a hang).  One JSON line per trial: the delay, the seconds
the child took to end after the signal (null: it hung), its exit status, the temporaries left behind, and
whether the output is there and reads back whole.
"""
from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

HANG = 20.0  # seconds: a child that has not ended by then hangs

SCENE = """\
name = "written"
[grid]
shape = [{n}, {n}]
[time]
t_end = 0.02
steps = 2
outputs = {outputs}
[[biofilm]]
shape = "sphere"
center = [{c}, {c}]
radius = 4.0
[[nutrient]]
shape = "box"
lower = [{edge}, {edge}]
upper = [{n}.0, {n}.0]
"""


def prepare(directory: Path, kind: str) -> list[str]:
    """The command line of a trial, with everything it needs in place."""
    import solver
    from biostudy.cli import app
    from biostudy.inputs.scene import load_scene

    if kind == "run":
        scene = directory / "written.toml"
        scene.write_text(SCENE.format(n=64, c=32.0, edge=60.0, outputs=40))
        ready = solver.simulate(load_scene(scene).problem())
        solver.simulate = lambda *args, **kwargs: ready
        return ["run", str(scene), "-o", str(directory / "out.nc"), "-q"]
    scene = directory / "written.toml"
    scene.write_text(SCENE.format(n=24, c=12.0, edge=20.0, outputs=10))
    study = directory / "study.toml"
    study.write_text('scene = "written.toml"\n[sweep]\ng = [1e8, 1e10]\n')
    args = ["sweep", str(study), "-o", str(directory / "out"), "-q"]
    child(app, args)  # the cases, once: every trial then writes study.nc from them
    return args


def started(app, args: list[str]) -> int:
    """The pid of a forked child running the command in-process, as `biostudy` does."""
    pid = os.fork()
    if pid == 0:
        try:
            app(args)
        except SystemExit as end:
            os._exit(end.code if isinstance(end.code, int) else 1)
        os._exit(0)
    return pid


def child(app, args: list[str]) -> int:
    return os.waitstatus_to_exitcode(os.waitpid(started(app, args), 0)[1])


def output(directory: Path, kind: str) -> Path:
    return directory / ("out.nc" if kind == "run" else "out/study.nc")


def main(directory: Path, kind: str, trials: int, sent_signal: signal.Signals = signal.SIGTERM) -> None:
    from biostudy.cli import app
    from biostudy.data import netcdf_io

    directory = directory / f"{kind}-{sent_signal.name}"
    directory.mkdir()
    args = prepare(directory, kind)
    began = time.monotonic()
    assert child(app, args) == 0
    took = time.monotonic() - began
    first = 0.0 if kind == "run" else 0.5  # a sweep reads its cases back before it writes study.nc
    for trial in range(trials):
        if kind == "run":
            output(directory, kind).unlink(missing_ok=True)
        delay = (first + (1.1 - first) * (trial + 0.5) / trials) * took
        pid = started(app, args)
        time.sleep(delay)
        os.kill(pid, sent_signal)
        sent = time.monotonic()
        status = None
        while time.monotonic() - sent < HANG:
            done, code = os.waitpid(pid, os.WNOHANG)
            if done:
                status = os.waitstatus_to_exitcode(code)
                break
            time.sleep(0.005)
        ended = time.monotonic() - sent if status is not None else None
        if status is None:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        target = output(directory, kind)
        print(json.dumps({"kind": kind, "signal": sent_signal.name, "delay": delay, "took": took, "ended": ended,
                          "status": status,
                          "temporaries": sorted(p.name for p in target.parent.glob(".*.tmp")),
                          "output": target.exists(),
                          "whole": target.exists() and netcdf_io.intact(target)}), flush=True)


if __name__ == "__main__":
    for given in sys.argv[2:]:
        name, count, *sent = given.split(":")
        main(Path(sys.argv[1]), name, int(count), signal.Signals["SIG" + (sent[0] if sent else "TERM")])
