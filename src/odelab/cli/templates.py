"""Starter experiment files for ``odelab new`` (the files live in odelab/templates/)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["KINDS", "write_template"]

def _folder():
    return resources.files("odelab").joinpath("templates")


# One starter per file in odelab/templates/: a new kind of starter is one new file. The system
# kinds first, in the order a course meets them, then the rest alphabetically.
_ORDER = ("ode", "state-space", "diagram", "network", "python", "sweep", "study")
KINDS = tuple(sorted((p.name[:-5] for p in _folder().iterdir() if p.name.endswith(".toml")),
                     key=lambda k: (_ORDER.index(k) if k in _ORDER else len(_ORDER), k)))


def _read(name: str) -> str:
    return _folder().joinpath(name).read_text(encoding="utf-8")


def schema_line() -> str:
    """``#:schema file:///.../odelab/schemas/experiment.schema.json``: a TOML editor (Taplo, VS Code's Even
    Better TOML) completes the file's keys and shows their reference entries; any other reader sees a comment."""
    from odelab.experiment.jsonschema import shipped_path

    return f"#:schema {Path(str(shipped_path())).resolve().as_uri()}\n"


def write_template(file: Path, kind: str, *, force: bool = False) -> list[Path]:
    """Write a commented starter experiment (and, for ``python``, its function file)."""
    if kind not in KINDS:
        raise ValueError(f"`--kind` is {kind!r}; choose one of {', '.join(KINDS)}.")
    file = Path(file)
    if file.suffix != ".toml":
        raise ValueError(f"{file}: experiment files end in .toml; try {file.with_suffix('.toml')}.")
    targets = {file: schema_line() + _read(f"{kind}.toml")}
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
