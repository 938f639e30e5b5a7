"""Fixtures of the grading tests (the helpers are in grading_support.py, next to this file)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from grading_support import EXERCISE1, EXERCISE1_RUBRIC, write_class  # noqa: E402


@pytest.fixture
def make_class(tmp_path):
    """make(students, reference=..., rubric=...) -> the rubric's path, the class under tmp_path."""
    def make(students, *, reference=None, rubric=EXERCISE1_RUBRIC):
        return write_class(tmp_path, reference or {"exercise1.toml": EXERCISE1}, students, rubric)

    return make
