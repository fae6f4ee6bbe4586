"""Shared fixtures of the Python tests (scripts/test.sh runs them with .deps/python)."""

import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DATA = pathlib.Path(os.environ.get("STIPPLE_DATA_DIR", ROOT.parent / "shared" / "data"))


@pytest.fixture
def data():
    """../shared/data (real LAS/LAZ/COPC files); tests that need it skip without it."""
    if not (DATA / "las" / "autzen_trim.las").exists():
        pytest.skip(f"{DATA} is absent (the real test data lives in ../shared/data)")
    return DATA


@pytest.fixture(scope="session")
def stipple_cli():
    """The command-line program built by scripts/setup.sh (build/stipple)."""
    exe = pathlib.Path(os.environ.get("STIPPLE_EXE", ROOT / "build" / "stipple"))
    if not exe.exists():
        pytest.skip(f"{exe} is not built")
    return exe
