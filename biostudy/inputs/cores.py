"""The processors a run may use here: the fewest of those the kernel lets it run on, its job's CPU quota and a
scheduler's allocation, as `memory` finds the memory.

- affinity: the processors this process may be scheduled on (``os.sched_getaffinity``: what taskset, a cpuset or
  a batch job's binding leaves it; the machine's count where there is no affinity);
- the cgroup: the tightest CPU quota from the job's own group up to the root (v2: ``cpu.max``, "quota period";
  v1: ``cpu.cfs_quota_us`` / ``cpu.cfs_period_us`` under the cpu controller), whole processors of it (at least
  one): a quota of 2.5 processors runs 2 threads at full speed;
- SLURM: ``SLURM_CPUS_PER_TASK`` (--cpus-per-task), else ``SLURM_CPUS_ON_NODE`` (the job's processors here).

``BIOSTUDY_THREADS`` (a whole number), when set, is the user's word and replaces them all.  A run names its own
count in its scene (``[numerics] threads``) or on the command line (``--threads``); this is the default.  The
roots of /proc and /sys are arguments so that tests can hand in a fake tree.
"""
from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ..errors import BadInput
from . import memory

VARIABLE = "BIOSTUDY_THREADS"


@dataclass(frozen=True)
class Cores:
    """Processors a run may use by one account, and which: 'affinity', 'cgroup v2 /slurm/job_7', ..."""

    count: int
    source: str


def affinity() -> Cores:
    try:
        return Cores(len(os.sched_getaffinity(0)), "affinity")
    except AttributeError:  # no affinity on this platform (macOS)
        return Cores(os.cpu_count() or 1, "the machine")


def _quota(text: str) -> float | None:
    """Processors of a quota 'quota period' (v2's cpu.max; v1's two files joined); None when unlimited."""
    parts = text.split()
    try:
        quota, period = float(parts[0]), float(parts[1])
    except (IndexError, ValueError):
        return None
    return quota / period if quota > 0 and period > 0 else None


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def _tightest(root: Path, group: str, version: str, read) -> Cores | None:
    """The smallest quota of a hierarchy, from the group's level up to the root."""
    found = None
    for level in memory.levels(root, group):
        processors = read(level)
        if processors is not None and (found is None or processors < found[0]):
            found = (processors, "/" + level.relative_to(root).as_posix() if level != root else "/")
    if found is None:
        return None
    return Cores(max(1, math.floor(found[0])), f"cgroup {version} {found[1]}")


def cgroup(proc: Path | None = None, sys: Path | None = None) -> Cores | None:
    """Whole processors of this process's CPU quota (v2, and v1's cpu controller), the tighter; None if none."""
    proc, sys = proc or memory.PROC, sys or memory.SYS
    mine = memory.groups(proc)
    found = []
    if "v2" in mine:
        found.append(_tightest(sys / "fs" / "cgroup", mine["v2"], "v2",
                               lambda level: _quota(_read(level / "cpu.max") or "")))
    if "cpu" in mine:
        root = next((sys / "fs" / "cgroup" / name for name in ("cpu", "cpu,cpuacct")
                     if (sys / "fs" / "cgroup" / name).is_dir()), sys / "fs" / "cgroup" / "cpu")
        found.append(_tightest(root, mine["cpu"], "v1", lambda level: _quota(
            f"{_read(level / 'cpu.cfs_quota_us') or ''} {_read(level / 'cpu.cfs_period_us') or ''}")))
    found = [cores for cores in found if cores is not None]
    return min(found, key=lambda cores: cores.count) if found else None


def scheduler(environ: Mapping[str, str] | None = None) -> Cores | None:
    """What a SLURM job was granted for this task on this node, from its environment; None outside such a job."""
    environ = os.environ if environ is None else environ
    for name in ("SLURM_CPUS_PER_TASK", "SLURM_CPUS_ON_NODE"):
        count = memory.integer(environ, name)
        if count:
            return Cores(count, f"{name}={count}")
    return None


def limits(proc: Path | None = None, sys: Path | None = None,
           environ: Mapping[str, str] | None = None) -> list[Cores]:
    """Every account of the processors a run may use here, the binding (fewest) first."""
    found = [affinity(), cgroup(proc, sys), scheduler(environ)]
    return sorted((cores for cores in found if cores is not None), key=lambda cores: cores.count)


def available(environ: Mapping[str, str] | None = None) -> Cores:
    """The processors a run may use here: BIOSTUDY_THREADS if set (`BadInput` if it is not a whole number of at
    least 1), else the fewest of `limits`."""
    environ = os.environ if environ is None else environ
    given = environ.get(VARIABLE, "").strip()
    if given:
        if not given.isdigit() or int(given) < 1:
            raise BadInput(f"{given!r} is not a whole number of threads of at least 1", VARIABLE)
        return Cores(int(given), f"{VARIABLE}={given}")
    return limits(environ=environ)[0]
