"""The Python API called from several threads of one process, as a notebook's may: HDF5 is not thread-safe, so
every netCDF call is serialised (`data.netcdf_io.HDF5`); one output is claimed by one writer, thread or process."""
import gc
import subprocess
import sys
import textwrap
import threading

import pytest
from conftest import TINY_SCENE

import biostudy

# Three threads opening a run's file 60 times each: SIGSEGV or SIGBUS before every netCDF call, xarray's metadata
# reads included, was made under one lock (issue 25: two threads of 50 opens crashed in 4 of 4 runs; three of 150
# in 5 of 6 tries here); about 2 s with it.
CRASH = textwrap.dedent("""\
    import threading
    import biostudy

    biostudy.run("tiny.toml", set={"time.steps": 4}, output="a.nc")
    def opens():
        for _ in range(60):
            biostudy.open("a.nc").close()
    threads = [threading.Thread(target=opens) for _ in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    print("survived")
    """)


def test_threads_opening_files_do_not_crash_the_interpreter(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY_SCENE)
    done = subprocess.run([sys.executable, "-c", CRASH], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and "survived" in done.stdout, (done.returncode, done.stderr[-2000:])


@pytest.fixture
def no_collection_in_threads():
    """Files other tests left to the garbage collector (xarray's own handles, closed under xarray's locks, not
    `netcdf_io.HDF5`) are closed here, in this thread, before threads of this test use HDF5 under biostudy's lock."""
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


def test_a_second_thread_writing_the_same_output_is_refused_at_once_and_the_first_completes(tiny_scene, tmp_path,
                                                                                             no_collection_in_threads):
    out = tmp_path / "run.nc"
    stepping, go_on = threading.Event(), threading.Event()
    ended = []

    def held(progress):  # the first run waits in its first step until the second has been answered
        stepping.set()
        go_on.wait(60)

    def first():
        ended.append(biostudy.run(tiny_scene, set={"time.steps": 4}, output=out, progress=held))

    thread = threading.Thread(target=first)
    thread.start()
    try:
        assert stepping.wait(60)
        with pytest.raises(biostudy.BadInput, match="another biostudy run .* is computing this output") as refused:
            biostudy.run(tiny_scene, set={"time.steps": 4}, output=out)
        assert len(refused.value.lines()) == 1
    finally:
        go_on.set()
        thread.join(120)
    assert ended and biostudy.open(out).attrs["steps_nominal"] == 4  # (its steps split to the Courant limit)


# Issue 39.3: eight threads of a fresh process read their first real times at once: four show a calibration file
# with t_ref (what it needs), four calibrate it into one directory.  pint's registry, made lazily, was made by
# several threads, and quantities of two registries do not compute together: 3 of 4 raised "Cannot operate with
# Quantity and Quantity of different registries", which also replaced the refusal of a directory in use.
FIRST_TIMES = textwrap.dedent("""\
    import threading
    import biostudy

    said = {}
    def call(name, function, *args, **options):
        try:
            found = function(*args, **options)
            said[name] = str(found) if name.startswith("show") else type(found).__name__
        except Exception as error:
            said[name] = f"{type(error).__name__}: {error}"
    threads = [threading.Thread(target=call, args=(f"calibrate{i}", biostudy.calibrate, "c.toml", "out"))
               for i in range(4)]
    threads += [threading.Thread(target=call, args=(f"show{i}", biostudy.show, "c.toml")) for i in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for name, value in sorted(said.items()):
        print(name, "|", value.splitlines()[0])
    """)


def test_threads_reading_their_first_real_times_share_one_unit_registry(tmp_path):
    from test_calibration_hostile import calibration, table

    calibration(tmp_path, table(("biomass", "", 0.05, 2.0, 0.1), ("biomass", "", 0.1, 2.2, 0.1)),
                '[estimate]\nr = [50.0, 150.0]\n[method]\nstarts = 1\nprofiles = false\n')
    done = subprocess.run([sys.executable, "-c", FIRST_TIMES], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300)
    said = dict(line.split(" | ", 1) for line in done.stdout.splitlines())
    assert done.returncode == 0 and len(said) == 8, done.stderr[-2000:]
    assert all(said[f"show{i}"].startswith("c: 1 parameters, 2 measurements") for i in range(4)), said
    calibrations = sorted(said[f"calibrate{i}"] for i in range(4))
    assert calibrations[-1] == "Dataset", said  # one calibrated
    assert all(text.startswith("BadInput: ") and "another biostudy run is writing into this directory" in text
               for text in calibrations[:3]), said  # the others refused at once, naming the one that writes
