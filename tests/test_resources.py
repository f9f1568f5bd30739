"""The memory estimate (`biostudy.inputs.resources`) against a measured peak, and where the available memory
comes from."""
import subprocess
import sys
from pathlib import Path

import pytest

from biostudy.errors import BadInput
from biostudy.inputs import resources

STUDIES = Path(__file__).resolve().parents[1] / "studies"
# The peak is the process's own high-water mark (VmHWM), not getrusage's ru_maxrss, which Linux carries over from
# the parent that forked it (a test runner of 700 MB would be measured, not the run).
PEAK = """\
import re, sys
from biostudy.inputs import resources
from biostudy.inputs.scene import load_scene
import solver
scene = load_scene(sys.argv[1], sys.argv[2:])
solver.simulate(scene.problem())
peak = int(re.search(r"VmHWM:\\s+(\\d+) kB", open("/proc/self/status").read()).group(1)) * 1024
print(resources.estimate(scene).memory, peak)
"""


@pytest.mark.parametrize("overrides", [
    ["grid.shape=[40,40,40]", "grid.spacing=0.5", "time.steps=10", "mechanics.enabled=false"],  # transport
    ["grid.shape=[24,24,24]", "grid.spacing=0.8333333333333334", "time.steps=10", "time.outputs=2"],  # mechanics
])
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs Linux's /proc to read a peak")
def test_the_memory_estimate_is_within_its_stated_factor_of_a_measured_peak(overrides):
    """resources' docstring: each part measured on this solver, the sum within a factor of ~1.5 of a run's peak
    resident memory (a fresh interpreter, as a worker is)."""
    done = subprocess.run([sys.executable, "-c", PEAK, str(STUDIES / "directional.toml"), *overrides],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    estimate, peak = map(float, done.stdout.split())
    assert 1 / 1.5 <= peak / estimate <= 1.5, (estimate, peak)


def test_the_available_memory_is_the_machines_within_its_cgroup_or_as_given(monkeypatch, tmp_path):
    monkeypatch.setenv("BIOSTUDY_MEMORY", "3.5 GB")
    assert resources.available_memory() == 3.5e9
    monkeypatch.setenv("BIOSTUDY_MEMORY", "lots")
    with pytest.raises(BadInput, match="BIOSTUDY_MEMORY: 'lots' is not a size"):
        resources.available_memory()
    monkeypatch.delenv("BIOSTUDY_MEMORY")
    (tmp_path / "memory.max").write_text("2000000000\n")
    (tmp_path / "memory.current").write_text("500000000\n")
    monkeypatch.setattr(resources, "CGROUP", tmp_path)
    assert resources.available_memory() == pytest.approx(1.5e9)  # a batch job's limit, below the machine's
    (tmp_path / "memory.max").write_text("max\n")
    assert resources.available_memory() > 1.5e9


@pytest.mark.parametrize("text, size", [("16 GB", 16e9), ("512MB", 512e6), ("2.5e9", 2.5e9), (".5 gb", 0.5e9)])
def test_sizes_read_as_people_write_them(text, size):
    assert resources.parse_size(text) == size


def test_a_size_in_other_units_is_refused():
    with pytest.raises(ValueError):
        resources.parse_size("3 GiB")


def test_a_streamed_runs_estimate_does_not_grow_with_its_outputs():
    """Issue 29.1: `biostudy run` streams its outputs to disk, so its estimate holds a few outputs' fields and a
    little bookkeeping per output; a sweep's case (held) still holds every output about three times over."""
    from biostudy.inputs.scene import load_scene

    def outputs(count: int, streamed: bool) -> float:
        scene = load_scene(STUDIES / "directional.toml", ["grid.shape=[64,64,64]", "grid.spacing=0.3125",
                                                           "time.steps=80", f"time.outputs={count}",
                                                           "mechanics.enabled=false"])
        return resources.estimate(scene, streamed=streamed).memory

    one_output = 3 * 8 * 64**3
    assert outputs(81, True) - outputs(5, True) < one_output  # bookkeeping only
    assert outputs(81, False) - outputs(5, False) > 3 * 76 * one_output
    assert outputs(81, True) < 1.15 * outputs(5, True)
