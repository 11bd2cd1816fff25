"""The benchmark's own modules (benchmarks/*.py), loaded by path for tests that check them
or build on their cases (benchmarks/ is not a package)."""

import importlib.util
import pathlib
import sys

_BENCH = pathlib.Path(__file__).resolve().parents[2] / "benchmarks"


def load(name):
    """benchmarks/<name>.py as a module."""
    key = f"_bench_{name}"
    if key not in sys.modules:  # registered first: dataclasses look their module up
        spec = importlib.util.spec_from_file_location(key, _BENCH / f"{name}.py")
        sys.modules[key] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules[key])
    return sys.modules[key]
