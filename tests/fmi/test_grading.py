"""odelab grade never loads a student's FMU unless the instructor passes --allow-native."""

from __future__ import annotations

import shutil
import tomllib

import pytest

pytest.importorskip("fmpy")

SUBMISSION = '[system]\nkind = "fmu"\nfile = "Dahlquist.fmu"\n[time]\nstop = 1\n'


def test_a_students_fmu_is_refused_unless_allowed(test_fmus, tmp_path):
    from odelab.experiment.cases import LoadedExperiment
    from odelab.fmi import fmu as fmu_module
    from odelab.grading.grade import _load_student_file
    from odelab.grading.submissions import Student, StudentFile

    folder = tmp_path / "alice"
    folder.mkdir()
    shutil.copy(test_fmus["Dahlquist"], folder / "Dahlquist.fmu")
    (folder / "exercise1.toml").write_text(SUBMISSION)
    student = Student("alice", folder)
    file = StudentFile(folder / "exercise1.toml", data=tomllib.loads(SUBMISSION))
    opened = set(fmu_module._OPENED)
    refused = _load_student_file(student, file, limits=None, allow_python=False)
    assert refused.message == ("`system.file` is 'Dahlquist.fmu', an FMU; grading never runs a submission's machine "
                               "code. Write the system as [system.equations] (or a state-space model); the instructor "
                               "can allow FMUs with `odelab grade --allow-native`.")
    assert set(fmu_module._OPENED) == opened  # nothing was unpacked or loaded
    from odelab.experiment.limits import DEFAULT_LIMITS

    (loaded,) = _load_student_file(student, file, DEFAULT_LIMITS, False, allow_native=True)
    assert isinstance(loaded, LoadedExperiment) and loaded.cases[0].problem.states == ("x",)
