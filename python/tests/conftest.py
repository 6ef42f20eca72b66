"""Shared fixtures of the opl Python tests.

Run by ctest (test python_pytest) with PYTHONPATH pointing at the module built
in build/python and OPL_SOURCE_DIR / OPL_BINARY_DIR set; by hand:
  PYTHONPATH=build/python OPL_SOURCE_DIR=$PWD OPL_BINARY_DIR=$PWD/build \
    python3 -m pytest python/tests
"""
import os
import pathlib

import numpy as np
import pytest

import opl

SOURCE_DIR = pathlib.Path(os.environ.get("OPL_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
BINARY_DIR = pathlib.Path(os.environ.get("OPL_BINARY_DIR", SOURCE_DIR / "build"))
EXAMPLES = SOURCE_DIR / "examples"


@pytest.fixture
def examples():
    return EXAMPLES


@pytest.fixture
def apps_dir():
    return BINARY_DIR / "apps"


@pytest.fixture
def prototype_design():
    """The prototype: two 11 x 11 sources 55 mm apart, a screen 1 m ahead."""
    return opl.ModuleDesign.read(str(EXAMPLES / "prototype_design.json"))


def rotation_xyz(a, b, c):
    """R = Rx(a) Ry(b) Rz(c), written out in numpy (independent of opl)."""
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
    ry = np.array([[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]])
    rz = np.array([[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]])
    return rx @ ry @ rz
