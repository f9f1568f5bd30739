"""Which files the package holds; its metadata is in pyproject.toml.

The bundled scenes, studies, catalogues and example data stay in `studies/` at the top of the checkout (the
paths README.md, docs/, tests and CI use) and are installed as the package data `biostudy/studies`, so a plain
`pip install .` or a wheel runs `biostudy run directional` from any directory.  pyproject.toml alone cannot map
a folder outside the package into it next to the automatic package discovery, hence this file.
"""
from setuptools import find_packages, setup

setup(packages=find_packages(include=["solver*", "biostudy*"]) + ["biostudy.studies"],
      package_dir={"biostudy.studies": "studies"},
      package_data={"biostudy.studies": ["*.toml", "*.tsv"]})
