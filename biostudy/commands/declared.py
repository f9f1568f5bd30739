"""Every command's options, declared once: the command line (`cli.app`) and the Python functions (`biostudy.api`)
are both made from these (`options`), so that they cannot differ.

An option taken by several commands is declared once here and shared (a function where it differs, as
`overrides` says what --set applies to).  Adding an option is one `Option` in its command's tuple and its use in the
command's `load`, which takes the options by these names (the job options, `EXECUTION`, go to `Execution`).
Kept to the standard library and constants: the command line is built from this module when it starts.
"""
from __future__ import annotations

from ..plans.refinement import FIRST_TOLERANCE, SERIES
from .kinds import Fraction, Named, Numbers
from .options import (
    REQUIRED,
    Choice,
    Command,
    File,
    Flag,
    Function,
    Many,
    Option,
    Overrides,
    Real,
    Source,
    Text,
    Time,
    Whole,
)

SET_HELP = "override a scene key, KEY=VALUE with the value as TOML (params.g=1e10, grid.shape=[40,40,40]); repeatable"


def overrides(applied: str = "") -> Option:
    """--set, saying what it applies to (a run's scene, every case, level 0)."""
    return Option("set", Overrides(), None, SET_HELP + (f"; applied to {applied}" if applied else ""), ("--set",),
                  "KEY=VALUE")


def source(name: str, metavar: str, help: str, *kinds: str, data: bool = False) -> Option:  # noqa: A002
    """The file a command reads, first: a path or a bundled file's name (`kinds`: which, for shell completion)."""
    return Option(name, Source(data), REQUIRED, help, metavar=metavar, positional=True, complete=kinds)


def error_estimate(what: str) -> Option:
    """--error-estimate: each observable's discretisation error from cheaper companion runs, for `what`."""
    return Option("error_estimate", Flag(), False, f"also run the scene on 2x coarser cells with 2x and 4x longer "
                  f"steps (and 4x coarser) and add, {what}, each observable's estimated discretisation error "
                  "Q_error at every output (docs/accuracy.md, 'Error bars on a run')", ("--error-estimate",))


def directory(help: str) -> Option:  # noqa: A002
    """Where a job command writes: -o DIR, and from Python its second argument."""
    return Option("directory", File(), None, help, ("-o", "--output"), "DIR", positional=True)


WORKERS = Option("workers", Whole(least=1, of="processes"), None, "run the cases on N local processes",
                 ("--workers",), "N")
SCHEDULER = Option("scheduler", Text("a Dask scheduler's address"), None, "address of a running Dask scheduler, "
                   "e.g. tcp://10.0.0.5:8786 or tls://... (docs/clusters.md, 'Local workers and a Dask cluster')",
                   ("--scheduler",), "ADDRESS")
SCHEDULER_FILE = Option("scheduler_file", File(), None, "the file a Dask scheduler wrote (`dask scheduler "
                        "--scheduler-file FILE`): how a batch job finds the cluster it started (docs/clusters.md, "
                        "'Dask inside an allocation')", ("--scheduler-file",), "FILE")
FORCE = Option("force", Flag(), False, "use the output directory even if it belongs to another study or holds files "
               "no biostudy run recorded (cases of the same ids are replaced)", ("--force",))
RERUN_ALL = Option("rerun_all", Flag(), False, "run every case again, also those finished before (e.g. after a "
                   "software upgrade)", ("--rerun-all",))
RETRY_FAILED = Option("retry_failed", Flag(), False, "run failed cases again (finished ones are skipped unless "
                      "--rerun-all)", ("--retry-failed",))
THREADS = Option("threads", Whole(least=1, of="threads"), None, "threads of each simulation (default: the scene's "
                 "numerics.threads, else the processors here, shared among a sweep's workers); the results are the "
                 "same for every count", ("--threads",), "N")
EXECUTION = ("workers", "scheduler", "scheduler_file", "retry_failed", "rerun_all", "force", "threads")  # `Execution`'s
WHERE = (WORKERS, SCHEDULER, SCHEDULER_FILE)
ARRAY_TASKS = "array tasks are batch jobs of the command line (docs/clusters.md)"
FORMATS = ("vti", "vtu", "tiff")  # the first is the default

RUN = Command("run", "Run one simulation and write its dataset (netCDF).", (
    source("scene", "SCENE", "scene file (TOML), or the name of a bundled scene; from Python also the scene's data "
           "as a dict (the tables of a scene file: {'grid': {'shape': [20, 20]}, 'time': {...}, ...})", "scene",
           data=True),
    overrides(),
    Option("output", File(), None, "dataset to write (default: NAME.nc, the scene's name; from Python: the dataset "
           "is returned, and written only if this is given)", ("-o", "--output"), "OUT.nc"),
    Option("continue_from", File(), None, "go on from the last state of this finished run of the same scene (give "
           "a later --set time.t_end=...); writes the whole history (default: RUN-tT_END.nc beside it)",
           ("--continue",), "RUN.nc"),
    Option("force", Flag(), False, "replace OUT.nc even if it holds the result of another scene or a sweep's file "
           "(never an input or a file biostudy did not write)", ("--force",)),
    error_estimate("to the dataset"),
    Option("progress", Function(), None, "called with a `solver.Progress` after every step", side="python",
           why="the command line draws its own progress (-q leaves it out)"),
    THREADS,
), "the run's dataset, the one the command writes; keys that `set` overrides are scalar coordinates of it (runs "
   "with different values combine with xr.open_mfdataset(files, combine='nested', concat_dim=KEY))")

SWEEP = Command("sweep", "Run every case of a study; re-running skips finished cases.", (
    source("study", "STUDY", "study file (TOML), or the name of a bundled study", "study"),
    directory("directory for cases/ and the results (default: from the file's name)"),
    *WHERE,
    overrides("every case"),
    RETRY_FAILED, RERUN_ALL, FORCE, THREADS,
    error_estimate("to every case's file and to study.nc"),
    Option("cases", Many(Text("a case id"), "a case id or a list of them"), None, "run only this case (an array "
           "task; repeatable): its file goes into DIR beside those of other such tasks; study.nc is left to "
           "--combine", ("--case",), "ID", side="cli", why=ARRAY_TASKS),
    Option("task", Whole(), None, "an array task: run case number N (the study's order from 0), or with --tasks M "
           "share N (0..M-1): cases N, N+M, ...", ("--task",), "N", side="cli", why=ARRAY_TASKS),
    Option("tasks", Whole(least=1), None, "how many shares --task numbers (fixed, not the array's size)",
           ("--tasks",), "M", side="cli", why=ARRAY_TASKS),
    Option("combine", Flag(), False, "run nothing: write DIR/study.nc from the case files there (after array "
           "tasks)", ("--combine",), side="cli", why=ARRAY_TASKS),
), "study.nc")

CALIBRATE = Command("calibrate", "Estimate scene parameters from measurements: least squares, profile likelihoods, "
                                 "95 % intervals.", (
    source("calibration", "FILE.toml", "calibration file (TOML: a scene, the data, the keys to estimate, the "
           "method), or the name of a bundled one", "calibration"),
    directory("directory for cases/, calibration.nc, calibration.md, the pictures and simulation.tsv (default: the "
              "calibration's name)"),
    *WHERE,
    overrides("the scene of every simulation"),
    RERUN_ALL, FORCE,
    error_estimate("for the simulation at the optimum, and compare it with each measurement's sigma in "
                   "calibration.md"),
), "calibration.nc: estimates, standard errors, 95 % profile intervals, which parameters the data determine, the "
   "data beside the fitted observables")

CONVERGENCE = Command("convergence", "Refine grid, time step and both; measure each level's error and cost "
                                     "(work-precision).", (
    source("scene", "SCENE", "scene file (TOML), or the name of a bundled scene", "scene"),
    directory("directory for cases/, convergence.nc, convergence.md, work_precision.png (default: "
              "NAME-convergence)"),
    Option("levels", Whole(least=2), 3, "levels per series; the finest is the reference", ("--levels",), "N"),
    Option("series", Choice(SERIES, "series", many=True), ",".join(SERIES), "comma-separated refinement series: "
           + ", ".join(SERIES), ("--series",), "S"),
    Option("tolerance", Real(least=0.0), FIRST_TOLERANCE, "time_tolerance of adaptive level 0 (divided by 4 per "
           "level)", ("--tolerance",), "TOL", unit="local error in phi per step"),
    *WHERE,
    overrides("level 0"),
    Option("reference", File(), None, "measure every level against this run of the same scene (e.g. refined, "
           "another scheme) instead of the finest level", ("--reference",), "RUN.nc"),
    Option("time", Real(), None, "compare at the output nearest this T* (default: the last)", ("--time",), "T",
           unit="T*"),
    Option("target_error", Fraction(what="a relative error"), None, "recommend the cheapest grid.shape, grid.spacing "
           "and time.steps predicted to reach this relative error in --observable at --time (the error model "
           "a h^p + b dt^q fitted to the levels; docs/accuracy.md)", ("--target-error",), "E"),
    Option("observable", Text("an observable's name"), "biofilm_volume", "the observable --target-error is for",
           ("--observable",), "NAME"),
    RERUN_ALL, FORCE,
), "convergence.nc: each level's error at every output against one reference, its cost, the observed orders, and "
   "with target_error the recommended resolution (attributes recommended_*)")

STABILITY = Command("stability", "Run stiff and extreme cases: each completes within its bounds or stops with a "
                                 "diagnosis.", (
    source("catalogue", "CATALOGUE", "stability catalogue (TOML), or the name of a bundled one", "stability"),
    directory("directory for cases/, stability.nc, stability.md (default: NAME-results)"),
    *WHERE,
    overrides("every case"),
    RERUN_ALL, FORCE,
), "stability.nc: each case's verdict (completed within its bounds, or stopped with a diagnosis)")

ANALYZE = Command("analyze", "Which parameter matters: Sobol' or Morris indices of a sampled study, rank "
                             "correlations of any study.", (
    Option("study", File(), REQUIRED, "a study's directory (or its study.nc), written by sweep", metavar="DIR",
           positional=True),
    Option("outputs", Many(Text("a name"), "a name or a list of names"), None, "observable or study.nc variable to "
           "analyse; repeatable (default: every observable the study has)", ("--output",), "NAME"),
    Option("times", Many(Time(), "a time or a list of times: T* as numbers, real times such as '12 h'"), None,
           "analyse at the output nearest this T* (or real time: '12 h', with the scene's t_ref); repeatable "
           "(default: the last output)", ("--time",), "T"),
), "analysis.nc (analysis.md and the pictures are written beside the study's study.nc)")

PLOT = Command("plot", "Draw the pictures of a run or a sweep: time series, cuts, isosurfaces, maps, sweep outputs.", (
    Option("result", File(), REQUIRED, "dataset written by run or sweep (a sweep's directory means its study.nc)",
           metavar="FILE.nc", positional=True),
    Option("output", File(), None, "picture (PNG); several figures get _series, _cut, ... suffixes (default: beside "
           "the dataset)", ("-o", "--output"), "FIG.png"),
    Option("variable", Text("a field or an output's name"), None, "one field (phi, c, alpha, p) or, for a sweep, one "
           "output (phi_mean, c_mean, biofilm_volume)", ("--variable",), "V"),
    Option("time", Time(), None, "draw the output nearest to this T* (or real time: '12 h', with the scene's t_ref)",
           ("--time",), "T"),
    Option("cut", Text("a cut"), None, "3-D: 'diagonal' (toward the nutrient, default), 'xy-diagonal', or a plane "
           "such as 'x=10' or 'z=5.5' (µm)", ("--cut",), "C"),
    Option("warp", Real(), None, "also draw the deformed body with the displacement magnified by this factor (e.g. "
           "500, paper Fig. 13)", ("--warp",), "FACTOR"),
), "the pictures written (paths)")

EXPORT = Command("export", "Write files ParaView opens (one VTK image per snapshot and a PVD listing them in time), "
                           "or TIFF stacks for Fiji.", (
    Option("result", File(), REQUIRED, "dataset written by run (or one case of a sweep)", metavar="FILE.nc",
           positional=True),
    Option("directory", File(), REQUIRED, "directory for snapshot_NNNN.vti files and series.pvd (vtu: .vtu; tiff: "
           "phi.tif, c.tif)", metavar="DIR", positional=True),
    Option("format", Choice(FORMATS, "format"), FORMATS[0], "vti: ParaView, VTK image data (default); vtu: ParaView, "
           "unstructured grid of the open cells; tiff: ImageJ hyperstacks of phi and c at scale (µm) with the time "
           "axis, for Fiji, BiofilmQ, COMSTAT", ("--format",), "F"),
), "the files written (paths)")

SHOW = Command("show", "Print a readable summary: scene, parameters, run time, final averages; for a scene or study "
                       "file what running it needs (memory, disk); for several runs, how they differ (scenes, "
                       "parameters, observables at their common times, the largest field differences).", (
    Option("paths", File(), REQUIRED, "dataset written by run or sweep (a case file, study.nc, or a sweep's "
           "directory), or a scene or study file (TOML); several runs: side by side", metavar="FILE...",
           positional=True, variadic=True),
), "a `Shown`: str() of it is what the command prints; `.record` the numbers of --json; for several runs "
   "`.comparison`")

SCENES = Command("scenes", "List the bundled scenes and studies with their descriptions.", (),
                 "the bundled files: `directory`, `entries` (`file`, `kind`, `description`), as --json prints them")

FACES = ("x-", "x+", "y-", "y+", "z-", "z+")
MEASURE = Command("measure", "Measure confocal stacks with the model's own COMSTAT code: biomass, mean and maximum "
                             "thickness, roughness, coverage, surface to biovolume, one row per frame "
                             "(docs/comstat.md, 'A lab's stacks').", (
    Option("stacks", File(), REQUIRED, "TIFF stack (z-y-x; a hyperstack's frames are times), or PNG/TIFF picture, "
           "segmented or greyscale; several: one after the other", metavar="STACK...", positional=True,
           variadic=True),
    Option("voxel", Numbers("voxel sizes", positive=True), None, "voxel size dz,dy,dx (a picture: dy,dx); default: "
           "the file's ImageJ or OME metadata", ("--voxel",), "DZ,DY,DX", unit="µm"),
    Option("threshold", Real(), None, "biofilm: values >= this (default: the stack must be segmented, 0 and one "
           "other value)", ("--threshold",), "T"),
    Option("substratum", Choice(FACES, "face"), None, "the face the biofilm grows on (default: the face the first "
           "frame's biofilm rests on, as for a scene)", ("--substratum",), "FACE"),
    Option("connected", Flag(), False, "COMSTAT's connected-volume filtering: only biofilm connected to the "
           "substratum counts", ("--connected",)),
    Option("petab", File(), None, "also write the PEtab measurement table a calibration reads (a new file: one that "
           "is there is never replaced)", ("--petab",), "OUT.tsv"),
    Option("time", Numbers("times"), None, "the time of every frame, in the order of the stacks (with --petab; in "
           "the unit the calibration names as its time_unit)", ("--time",), "T1,T2,..."),
    Option("condition", Text("a condition id"), "", "the measurement table's simulationConditionId",
           ("--condition",), "ID"),
    Option("noise", Named(), {}, "σ of an observable in its units (biomass=0.2; repeatable); default: a noise "
           "parameter per observable (sigma_biomass, ...) that the calibration estimates", ("--noise",),
           "OBS=SIGMA"),
), "one record per frame (file, frame, time, the six observables, substratum, threshold, voxel, shape, sha256), "
   "as --json prints them")

COMMANDS = (RUN, SWEEP, SCENES, SHOW, PLOT, ANALYZE, EXPORT, MEASURE, CONVERGENCE, STABILITY, CALIBRATE)
JOBS = (SWEEP, CONVERGENCE, STABILITY, CALIBRATE)  # `jobs.started`: their cases run here, on workers or a cluster
