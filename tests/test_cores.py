"""The threads a run takes by default: the processors this process may use (affinity, a job's cgroup quota, a
SLURM allocation, BIOSTUDY_THREADS) shared among the cases computed here at once."""
import dataclasses

import numpy as np
import pytest
from test_resources import fake_kernel

from biostudy.errors import BadInput
from biostudy.execution import worker
from biostudy.inputs import cores
from solver import Grid, Numerics, Problem


def test_a_cgroup_quota_is_the_tightest_whole_processors_from_the_jobs_group_up(tmp_path):
    """v2's cpu.max "quota period" at each level; 2.5 processors run 2 threads at full speed; "max" is none."""
    job = "fs/cgroup/system.slice/slurmstepd.scope/job_7"
    proc, sys_ = fake_kernel(tmp_path, "0::/system.slice/slurmstepd.scope/job_7/step_0\n", {
        f"{job}/step_0/cpu.max": "max 100000\n", f"{job}/cpu.max": "250000 100000\n",
        "fs/cgroup/system.slice/cpu.max": "800000 100000\n"})
    assert cores.cgroup(proc, sys_) == cores.Cores(2, "cgroup v2 /system.slice/slurmstepd.scope/job_7")
    (tmp_path / "sys" / job / "cpu.max").write_text("50000 100000\n")  # half a processor: one thread still
    assert cores.cgroup(proc, sys_).count == 1
    (tmp_path / "sys" / job / "cpu.max").write_text("max 100000\n")
    assert cores.cgroup(proc, sys_) == cores.Cores(8, "cgroup v2 /system.slice")


def test_a_cgroup_v1_cpu_quota_is_read_and_no_quota_is_none(tmp_path):
    job = "fs/cgroup/cpu,cpuacct/slurm/job_7"
    proc, sys_ = fake_kernel(tmp_path, "4:cpu,cpuacct:/slurm/job_7\n3:memory:/slurm/job_7\n", {
        f"{job}/cpu.cfs_quota_us": "400000\n", f"{job}/cpu.cfs_period_us": "100000\n",
        "fs/cgroup/cpu,cpuacct/cpu.cfs_quota_us": "-1\n", "fs/cgroup/cpu,cpuacct/cpu.cfs_period_us": "100000\n"})
    assert cores.cgroup(proc, sys_) == cores.Cores(4, "cgroup v1 /slurm/job_7")
    (tmp_path / "sys" / job / "cpu.cfs_quota_us").write_text("-1\n")
    assert cores.cgroup(proc, sys_) is None
    assert cores.cgroup(tmp_path / "nowhere", sys_) is None


@pytest.mark.parametrize("environ, count", [
    ({"SLURM_CPUS_PER_TASK": "6", "SLURM_CPUS_ON_NODE": "24"}, 6),
    ({"SLURM_CPUS_ON_NODE": "24(x2)"}, 24),
    ({"SLURM_JOB_ID": "7"}, None),
])
def test_a_slurm_allocation_is_read_from_the_jobs_environment(environ, count):
    found = cores.scheduler(environ)
    assert (found and found.count) == count


def test_the_fewest_processors_bind_unless_biostudy_threads_says(monkeypatch, tmp_path):
    proc, sys_ = fake_kernel(tmp_path, "0::/job_7\n", {"fs/cgroup/job_7/cpu.max": "300000 100000\n"})
    monkeypatch.setattr(cores.memory, "PROC", proc)
    monkeypatch.setattr(cores.memory, "SYS", sys_)
    monkeypatch.setattr(cores, "affinity", lambda: cores.Cores(32, "affinity"))
    assert cores.available({}) == cores.Cores(3, "cgroup v2 /job_7")
    assert cores.available({"SLURM_CPUS_PER_TASK": "2"}) == cores.Cores(2, "SLURM_CPUS_PER_TASK=2")
    assert cores.available({"SLURM_CPUS_PER_TASK": "2", "BIOSTUDY_THREADS": "12"}) == \
        cores.Cores(12, "BIOSTUDY_THREADS=12")
    for wrong in ("0", "two", "1.5"):
        with pytest.raises(BadInput, match="BIOSTUDY_THREADS: .* is not a whole number of threads"):
            cores.available({"BIOSTUDY_THREADS": wrong})


def test_cases_computed_at_once_share_the_processors_and_a_scenes_own_count_stands(monkeypatch):
    monkeypatch.setattr(cores, "available", lambda environ=None: cores.Cores(8, "affinity"))
    problem = Problem(grid=Grid((4, 4)), phi0=np.zeros((4, 4)), nutrient_held=np.ones((4, 4), bool), t_end=1.0, steps=1,
                      output_times=[1.0])
    assert worker.with_threads(problem).numerics.threads == 8
    assert worker.with_threads(problem, sharing=3).numerics.threads == 2
    assert worker.with_threads(problem, sharing=16).numerics.threads == 1
    own = dataclasses.replace(problem, numerics=Numerics(threads=5))
    assert worker.with_threads(own, sharing=3).numerics.threads == 5
