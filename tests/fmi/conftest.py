"""Session fixtures: odelab's test FMUs and the exported FMUs, each built once per test session."""

from __future__ import annotations

import subprocess
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "tests" / "assets" / "fmi" / "models"
TEST_FMUS = ("BouncingBall", "Dahlquist", "VanDerPol", "Stair", "Feedthrough")

pytest.importorskip("fmpy")


def fmi_headers() -> Path:
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


@pytest.fixture(scope="session")
def test_fmus(tmp_path_factory) -> dict[str, Path]:
    """odelab's five test FMUs (tests/assets/fmi/models), built with the C compiler: name -> .fmu."""
    from odelab.fmi.build import find_compiler, platform_folder

    folder = tmp_path_factory.mktemp("test_fmus")
    out = {}
    for name in TEST_FMUS:
        library = folder / f"{name}.so"
        subprocess.run([find_compiler(), "-shared", "-fPIC", "-O2", "-I", str(fmi_headers()), "-I", str(MODELS),
                        "-o", str(library), str(MODELS / f"{name}.c"), "-lm"], check=True, capture_output=True,
                       timeout=120)
        fmu = folder / f"{name}.fmu"
        with zipfile.ZipFile(fmu, "w") as z:
            z.write(MODELS / f"{name}.xml", "modelDescription.xml")
            z.write(library, f"binaries/{platform_folder()}/{name}.so")
        out[name] = fmu
    return out


EXPORTED = {"exercise2": "experiments/exercise2.toml", "network_msd": "experiments/networks/network_msd.toml",
            "network_nonlinear_spring": "experiments/networks/network_nonlinear_spring.toml",
            "pid_saturation": "tests/assets/fmi/pid_saturation.toml"}


def _export_all(folder: Path, version: int) -> dict[str, tuple]:
    from odelab import fmi
    from odelab.experiment.loader import load_experiment

    out = {}
    for name, path in EXPORTED.items():
        experiment = load_experiment(ROOT / path)
        out[name] = (fmi.export(experiment, folder / f"{name}.fmu", fmi=version), experiment.cases[0])
    return out


@pytest.fixture(scope="session")
def exported(tmp_path_factory) -> dict[str, tuple]:
    """The shipped experiments exported as FMI 2.0 (their first case): name -> (Exported, the loaded case)."""
    return _export_all(tmp_path_factory.mktemp("exported"), 2)


@pytest.fixture(scope="session")
def exported3(tmp_path_factory) -> dict[str, tuple]:
    """The same, as FMI 3.0."""
    return _export_all(tmp_path_factory.mktemp("exported3"), 3)
