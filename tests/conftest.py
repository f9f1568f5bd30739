"""Shared fixtures: tiny scene and study files for the study-service tests (biostudy/)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

# A 2-D 16 x 16 scene of 20 steps: ~0.1 s to simulate, yet every part of a scene is there.
TINY_SCENE = """\
name = "tiny"
description = "tiny test scene"

[grid]
shape = [16, 16]
spacing = 1.0

[params]
g = 1e8

[time]
t_end = 0.2
steps = 20
outputs = 3

[[biofilm]]
shape = "sphere"
center = [8.0, 8.0]
radius = 3.0

[[nutrient]]
shape = "box"
lower = [14.0, 14.0]
upper = [16.0, 16.0]

[[obstacle]]
shape = "box"
lower = [0.0, 12.0]
upper = [3.0, 16.0]
"""


@pytest.fixture
def write_toml(tmp_path):
    """write_toml(name, text) -> path of a TOML file in the test's directory (text is dedented)."""

    def write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path

    return write


@pytest.fixture
def tiny_scene(write_toml) -> Path:
    return write_toml("tiny.toml", TINY_SCENE)


@pytest.fixture
def tiny_study(write_toml, tiny_scene) -> Path:
    """A 2 x 2 grid sweep over g and r of the tiny scene."""
    return write_toml("tiny-sweep.toml", """\
        description = "tiny test sweep"
        scene = "tiny.toml"
        [sweep]
        mode = "grid"
        g = [1e8, 1e9]
        r = [50.0, 100.0]
        """)
