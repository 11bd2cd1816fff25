"""Shared pytest configuration.

Tests under tests/core need only numpy/scipy/scikit-image. Tests under
tests/blender need the bpy module (or a real ``blender -b``); they are marked
``blender`` automatically.
"""

import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "tests/blender" in str(item.fspath).replace("\\", "/"):
            item.add_marker(pytest.mark.blender)
