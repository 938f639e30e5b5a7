"""Starter experiment files for ``odelab new`` (the files live in odelab/templates/)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["KINDS", "write_template"]

KINDS = ("ode", "state-space", "python")


def _read(name: str) -> str:
    return resources.files("odelab").joinpath("templates", name).read_text(encoding="utf-8")


def write_template(file: Path, kind: str, *, force: bool = False) -> list[Path]:
    """Write a commented starter experiment (and, for ``python``, its function file)."""
    if kind not in KINDS:
        raise ValueError(f"`--kind` is {kind!r}; choose one of {', '.join(KINDS)}.")
    file = Path(file)
    if file.suffix != ".toml":
        raise ValueError(f"{file}: experiment files end in .toml; try {file.with_suffix('.toml')}.")
    targets = {file: _read(f"{kind}.toml")}
    if kind == "python":
        rhs = file.with_name(file.stem + "_rhs.py")
        targets[file] = targets[file].replace("RHS_FILE", rhs.name)
        targets[rhs] = _read("python_rhs.py")
    for path in targets:
        if path.exists() and not force:
            raise ValueError(f"{path} exists; choose another name or pass --force to overwrite it.")
    for path, text in targets.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return list(targets)
