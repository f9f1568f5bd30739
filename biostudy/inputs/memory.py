"""The memory a run may use here: the smallest of the machine's, its job's cgroup and a scheduler's allocation.

On a cluster the machine's free memory is not what a job may use: the batch system confines the job to a
control group (cgroup v2, or v1's memory controller) and says what it granted in the job's environment.  Each
is a `Limit` (bytes, and where it was read); the one that binds is the smallest.

- the machine: what psutil calls available;
- the cgroup: every level from the job's own group (named in /proc/self/cgroup) up to the root, each level's
  limit less what that level already uses (v2: memory.max, memory.current; v1: memory.limit_in_bytes,
  memory.usage_in_bytes under the memory controller);
- SLURM: `SLURM_MEM_PER_NODE` (--mem), or `SLURM_MEM_PER_CPU` (--mem-per-cpu) times the CPUs allocated here
  (`SLURM_CPUS_ON_NODE`, else `SLURM_CPUS_PER_TASK`); SLURM's megabytes are MiB;
- PBS (OpenPBS, PBS Pro, Torque) exports no memory request: its cgroup is read instead, or
  `BIOSTUDY_MEMORY` says it (docs/clusters.md).

`BIOSTUDY_MEMORY` (e.g. "16 GB"), when set, is the user's word and replaces them all.  The roots of /proc and
/sys are arguments so that tests can hand in a fake tree.
"""
from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

PROC, SYS = Path("/proc"), Path("/sys")  # where the kernel tells; tests point them at a fake tree
UNLIMITED = 2.0**60  # cgroup v1 writes "no limit" as a page-rounded 2^63 - 1
MIB = 1024.0**2  # SLURM's "MB"


@dataclass(frozen=True)
class Limit:
    """Bytes a run may use by one account, and which: 'the machine', 'cgroup v2 /slurm/job_7', ..."""

    bytes: float
    source: str


def _number(path: Path) -> float | None:
    """A cgroup file's number; None when absent, unreadable or 'max' (no limit)."""
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        return None
    return value if value < UNLIMITED else None


def groups(proc: Path) -> dict[str, str]:
    """This process's cgroup paths by hierarchy: {'v2': '/user.slice/...', 'memory': '/slurm/uid_1/job_7', 'cpu':
    ...} (v2's single hierarchy, and each controller of v1's)."""
    try:
        lines = (proc / "self" / "cgroup").read_text().splitlines()
    except OSError:
        return {}
    found = {}
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, path = parts
        if controllers == "":
            found["v2"] = path
        else:
            found.update((controller, path) for controller in controllers.split(","))
    return found


def levels(root: Path, group: str) -> list[Path]:
    """The group's directory under the hierarchy's mount, then each parent up to the mount itself."""
    here = root / group.strip("/")
    levels = []
    while True:
        levels.append(here)
        if here == root:
            return levels
        here = here.parent


def _room(root: Path, group: str, limit_file: str, usage_file: str, version: str) -> Limit | None:
    """The tightest level of one hierarchy: its limit less its usage (a level without a limit is no bound)."""
    tightest = None
    for level in levels(root, group):
        limit = _number(level / limit_file)
        if limit is None:
            continue
        room = max(0.0, limit - (_number(level / usage_file) or 0.0))
        if tightest is None or room < tightest.bytes:
            name = "/" + level.relative_to(root).as_posix() if level != root else "/"
            tightest = Limit(room, f"cgroup {version} {name}")
    return tightest


def cgroup(proc: Path | None = None, sys: Path | None = None) -> Limit | None:
    """Room under this process's cgroups (v2, and v1's memory controller), the tighter; None if unlimited."""
    proc, sys = proc or PROC, sys or SYS
    mine = groups(proc)
    found = []
    if "v2" in mine:
        found.append(_room(sys / "fs" / "cgroup", mine["v2"], "memory.max", "memory.current", "v2"))
    if "memory" in mine:
        found.append(_room(sys / "fs" / "cgroup" / "memory", mine["memory"], "memory.limit_in_bytes",
                           "memory.usage_in_bytes", "v1"))
    found = [limit for limit in found if limit is not None]
    return min(found, key=lambda limit: limit.bytes) if found else None


def integer(environ: Mapping[str, str], name: str) -> int | None:
    """A scheduler's count: '1500' -> 1500; SLURM's '2(x3)' repetition -> 2; absent or odd -> None."""
    text = environ.get(name, "").split("(")[0].split(",")[0].strip()
    return int(text) if text.isdigit() else None


def scheduler(environ: Mapping[str, str] | None = None) -> Limit | None:
    """What a SLURM job was granted on this node, from its environment; None outside such a job."""
    environ = os.environ if environ is None else environ
    per_node = integer(environ, "SLURM_MEM_PER_NODE")
    if per_node:
        return Limit(per_node * MIB, f"SLURM_MEM_PER_NODE={per_node} (MB)")
    per_cpu = integer(environ, "SLURM_MEM_PER_CPU")
    if per_cpu:
        for name in ("SLURM_CPUS_ON_NODE", "SLURM_CPUS_PER_TASK"):
            cpus = integer(environ, name)
            if cpus:
                return Limit(per_cpu * cpus * MIB, f"SLURM_MEM_PER_CPU={per_cpu} (MB) × {name}={cpus}")
        return Limit(per_cpu * MIB, f"SLURM_MEM_PER_CPU={per_cpu} (MB) × 1 CPU")
    return None


def machine() -> Limit:
    import psutil  # lazily: reading a run's file never asks

    return Limit(float(psutil.virtual_memory().available), "the machine")


def limits(proc: Path | None = None, sys: Path | None = None,
           environ: Mapping[str, str] | None = None) -> list[Limit]:
    """Every account of the memory a run may use here, the binding (smallest) first."""
    found = [machine(), cgroup(proc, sys), scheduler(environ)]
    return sorted((limit for limit in found if limit is not None), key=lambda limit: limit.bytes)
