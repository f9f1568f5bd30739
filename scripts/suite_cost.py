"""What each test costs in CPU seconds: a pytest plugin, for comparing tests before and after a change on a busy
machine, where wall times are not comparable.

    cd scripts/.. && PYTHONPATH=$PWD:$PWD/scripts python -m pytest -n 0 -p suite_cost tests/test_x.py

prints, after the run, the CPU seconds (user + system) of each test's setup, call and teardown, this process's
and its children's (the subprocesses and worker pools a test started and waited for), the slowest first, and
their sum per file.  CPU time counts what a test makes the machine do, which other load barely changes (wall
time under a load average of 10 doubles or triples); a file's sum is what it adds to the `--dist loadfile`
worker that runs it.  `-n 0`: xdist's workers would keep the figures to themselves.  Not counted: processes
that are not this one's children, such as the local pool's workers, which multiprocessing's fork server starts
(compare such tests by wall time on a quiet machine).
"""
from __future__ import annotations

import os
import resource
from collections import defaultdict

import pytest

_COST: dict[str, float] = defaultdict(float)


def cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its children that have been waited for."""
    own, children = os.times(), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.user + own.system + children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item):
    began = cpu_seconds()
    yield
    _COST[f"{item.nodeid} setup"] += cpu_seconds() - began


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    began = cpu_seconds()
    yield
    _COST[f"{item.nodeid} call"] += cpu_seconds() - began


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item):
    began = cpu_seconds()
    yield
    _COST[f"{item.nodeid} teardown"] += cpu_seconds() - began


def pytest_terminal_summary(terminalreporter):
    write = terminalreporter.write_line
    files: dict[str, float] = defaultdict(float)
    for key, seconds in _COST.items():
        files[key.split("::", 1)[0]] += seconds
    write("")
    write("CPU seconds per file (suite_cost):")
    for name, seconds in sorted(files.items(), key=lambda kv: -kv[1]):
        write(f"{seconds:8.2f}  {name}")
    write(f"{sum(files.values()):8.2f}  total")
    write("CPU seconds per test phase, slowest 25 (suite_cost):")
    for key, seconds in sorted(_COST.items(), key=lambda kv: -kv[1])[:25]:
        write(f"{seconds:8.2f}  {key}")
