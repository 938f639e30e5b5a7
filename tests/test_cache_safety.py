"""Every cache is untrusted: checked folders, sealed entries, recovery with a note, never planted code.

The compiled runs here are in-process (``odelab run`` through CliRunner), each with its own
cache root copied from one warm cache, so that numba compiles the lab's system once per module.
"""

import importlib.util
import marshal
import os
import pickle
import shutil
import stat
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from odelab import cachedir
from odelab.cli import app

ROOT = Path(__file__).resolve().parents[1]
EXERCISE1 = (ROOT / "experiments" / "exercise1.toml").read_text()
NOBODY = 65534


@pytest.fixture(autouse=True)
def no_notes_left():
    """The notes are per process: none left for the next test's cases."""
    yield
    cachedir.take_notes()


def _run_compiled(tmp_path, monkeypatch, root: Path):
    from odelab.solvers.compiled import cache

    monkeypatch.setenv("ODELAB_CACHE_DIR", str(root))
    monkeypatch.setattr(cache, "_LOADED", {})  # as a new process: the modules are run again from the cache
    cachedir.take_notes()
    path = tmp_path / "exercise1.toml"
    path.write_text(EXERCISE1)
    return CliRunner().invoke(app, ["run", str(path), "--backend", "compiled", "--no-store"])


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """A cache root holding the compiled lab system (sealed), to copy into each test."""
    pytest.importorskip("numba")
    root = tmp_path_factory.mktemp("warm") / "cache"
    with pytest.MonkeyPatch.context() as mp:
        result = _run_compiled(tmp_path_factory.mktemp("warm-run"), mp, root)
    assert result.exit_code == 0, result.output
    return root


def _copy(warm, tmp_path) -> Path:
    root = tmp_path / "cache"
    shutil.copytree(warm, root)  # modification times kept: numba's entries stay fresh
    return root


def _ok(result) -> str:
    assert result.exit_code == 0, result.output
    assert "Traceback" not in result.output
    assert "ode45 (compiled)" in result.output
    return result.output


def _entries(root: Path, suffix: str) -> list[Path]:
    return sorted((root / "compiled" / "__pycache__").glob(f"odelab_*{suffix}"))


class _Plant:
    """Unpickling it creates the marker file: what a planted numba index could do."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _plant_everything(root: Path, marker: Path, *, forge_seals: bool) -> None:
    """Replace every numba index and data file by a pickle that creates ``marker`` when loaded,
    and put beside every module a .pyc (valid for its source's time and size) that does too."""
    payload = pickle.dumps(_Plant(marker))
    for entry in _entries(root, ".nbi") + _entries(root, ".nbc"):
        entry.write_bytes(payload)
        if forge_seals:
            cachedir.seal(entry)
    code = compile(f"open({str(marker)!r}, 'w').close()\n", "planted", "exec")
    for module in (root / "compiled").glob("odelab_*.py"):
        st = module.stat()
        pyc = importlib.util.cache_from_source(str(module))
        data = importlib._bootstrap_external._code_to_timestamp_pyc(code, st.st_mtime, st.st_size)
        Path(pyc).write_bytes(bytes(data))
        assert marshal.loads(bytes(data)[16:]) is not None


def _chown_tree(root: Path, uid: int, mode: int) -> None:
    for folder, dirs, files in os.walk(root):
        os.chown(folder, uid, uid)
        os.chmod(folder, mode)
        for name in files:
            os.chown(os.path.join(folder, name), uid, uid)


needs_root = pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="chown to another user")


@needs_root
def test_code_planted_in_a_foreign_world_writable_cache_never_runs(warm, tmp_path, monkeypatch):
    root = _copy(warm, tmp_path)
    marker = tmp_path / "planted-code-ran"
    _plant_everything(root, marker, forge_seals=True)  # whoever can write the folder can forge the seals too
    _chown_tree(root, NOBODY, 0o777)
    out = _ok(_run_compiled(tmp_path, monkeypatch, root))
    assert not marker.exists()
    assert f"{root} belongs to another user (uid {NOBODY})" in out
    assert "private temporary cache" in out
    assert all(p.read_bytes() == pickle.dumps(_Plant(marker)) for p in _entries(root, ".nbi"))  # left alone


def test_a_world_writable_cache_of_ones_own_is_not_used_either(warm, tmp_path, monkeypatch):
    root = _copy(warm, tmp_path)
    marker = tmp_path / "planted-code-ran"
    _plant_everything(root, marker, forge_seals=True)
    os.chmod(root / "compiled", 0o777)
    out = _ok(_run_compiled(tmp_path, monkeypatch, root))
    assert not marker.exists()
    assert f"{root / 'compiled'} can be written by other users (mode 0777)" in out


def test_unsealed_entries_in_ones_own_cache_are_deleted_and_compiled_again(warm, tmp_path, monkeypatch):
    root = _copy(warm, tmp_path)
    marker = tmp_path / "planted-code-ran"
    _plant_everything(root, marker, forge_seals=False)
    for seal in (root / "compiled" / "__pycache__").glob("*.sha256"):
        seal.unlink()
    out = _ok(_run_compiled(tmp_path, monkeypatch, root))
    assert not marker.exists()
    assert "has no seal (odelab did not write it): deleted and made again" in out
    for entry in _entries(root, ".nbi"):  # compiled again, and sealed
        assert cachedir.verify(entry) is not None and pickle.dumps(_Plant(marker)) != entry.read_bytes()
    out = _ok(_run_compiled(tmp_path, monkeypatch, root))  # and the next run loads them without a note
    assert "note:" not in out


@pytest.mark.parametrize("kind", [".nbi", ".nbc", ".pyc", ".py"])
def test_a_truncated_cache_file_is_compiled_again_with_a_note(warm, tmp_path, monkeypatch, kind):
    root = _copy(warm, tmp_path)
    if kind == ".pyc":  # odelab writes none and never reads one: a damaged one changes nothing
        targets = []
        for module in (root / "compiled").glob("odelab_*.py"):
            Path(importlib.util.cache_from_source(str(module))).write_bytes(b"\x00\x01")
            targets.append(module)
    elif kind == ".py":
        targets = sorted((root / "compiled").glob("odelab_*.py"))
    else:
        targets = _entries(root, kind)
    assert targets
    if kind != ".pyc":
        for path in targets:
            with open(path, "r+b") as fh:
                fh.truncate(path.stat().st_size // 2)
    out = _ok(_run_compiled(tmp_path, monkeypatch, root))
    if kind in (".nbi", ".nbc"):
        assert "does not match its seal (damaged): deleted and made again" in out
        assert all(cachedir.verify(p) is not None for p in _entries(root, kind))
    elif kind == ".py":
        assert "was not the one odelab wrote (damaged or edited): written and compiled again" in out


@pytest.mark.parametrize("damage", ["read-only root", "read-only compiled", "file for root", "file for compiled",
                                    "file for __pycache__", "symlinked compiled"])
def test_an_unusable_cache_folder_falls_back_to_a_private_one(warm, tmp_path, monkeypatch, damage):
    root = _copy(warm, tmp_path)
    what, _, where = damage.partition(" for ") if " for " in damage else (damage, "", "")
    if damage == "read-only root":
        os.chmod(root, 0o555)
    elif damage == "read-only compiled":
        os.chmod(root / "compiled", 0o555)
    elif damage == "symlinked compiled":
        shutil.move(root / "compiled", tmp_path / "elsewhere")
        os.symlink(tmp_path / "elsewhere", root / "compiled")
    else:
        target = {"root": root, "compiled": root / "compiled", "__pycache__": root / "compiled" / "__pycache__"}[where]
        shutil.rmtree(target)
        target.write_text("a file where the folder should be\n")
    try:
        out = _ok(_run_compiled(tmp_path, monkeypatch, root))
    finally:
        for folder in (root, root / "compiled"):
            if folder.is_dir() and not folder.is_symlink():
                os.chmod(folder, 0o700)
    reason = {"read-only root": "is read-only (mode 0555)", "read-only compiled": "is read-only (mode 0555)",
              "symlinked compiled": "is a symbolic link"}.get(damage, "is a file, not a folder")
    assert reason in out and "private temporary cache" in out


@pytest.mark.parametrize("rule, make", [
    ("belongs to another user", lambda p: os.chown(p, NOBODY, NOBODY)),
    ("can be written by other users (mode 0777)", lambda p: os.chmod(p, 0o777)),
    ("can be written by other users (mode 0770)", lambda p: os.chmod(p, 0o770)),
    ("is read-only (mode 0500)", lambda p: os.chmod(p, 0o500)),
])
@pytest.mark.parametrize("level", ["root", "figures"])
def test_each_folder_rule_on_the_root_and_below_it(tmp_path, monkeypatch, rule, make, level):
    if "another user" in rule and os.geteuid() != 0:
        pytest.skip("chown to another user")
    root = tmp_path / "cache"
    (root / "figures").mkdir(parents=True, mode=0o700)
    os.chmod(root, 0o700)
    target = root if level == "root" else root / "figures"
    make(target)
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(root))
    cachedir.take_notes()
    try:
        folder = cachedir.cache_folder("figures")
    finally:
        os.chmod(target, 0o700)
    assert folder is not None and not str(folder).startswith(str(root))
    assert stat.S_IMODE(folder.parent.stat().st_mode) == 0o700 and folder.parent.stat().st_uid == os.geteuid()
    notes = cachedir.take_notes()
    assert any(f"{target} {rule}" in n and "private temporary cache" in n for n in notes), notes


def test_a_sound_cache_folder_is_used_and_made_private(tmp_path, monkeypatch):
    root = tmp_path / "new" / "cache"
    monkeypatch.setenv("ODELAB_CACHE_DIR", str(root))
    cachedir.take_notes()
    assert cachedir.cache_folder("templates/html-x") == root / "templates" / "html-x"
    assert all(stat.S_IMODE(p.stat().st_mode) == 0o700 for p in (root, root / "templates", root / "templates" / "html-x"))
    assert cachedir.take_notes() == []


def test_a_truncated_figure_is_drawn_again_never_embedded_broken(tmp_path, monkeypatch):
    from odelab.report import figcache, plots
    from odelab.report.plots import FigureSpec, Line, Panel

    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "cache"))
    t = np.linspace(0, 1, 5)
    spec = FigureSpec(name="a", caption="c", alt="a",
                      panels=(Panel(title="x(t)", xlabel="t", ylabel="x", lines=(Line(t, t**2, "ode45", "#000"),)),))
    png = plots.render_png(spec)
    cached = tmp_path / "cache" / "figures" / f"{figcache.figure_key(spec)}.png"
    assert cached.read_bytes() == png and png.endswith(b"IEND\xaeB`\x82")
    cached.write_bytes(png[: len(png) // 2])
    cachedir.take_notes()
    assert plots.render_png(spec) == png  # drawn again, whole
    assert any("does not match its seal (damaged)" in n for n in cachedir.take_notes())
    assert cached.read_bytes() == png
    cached.with_name(cached.name + ".sha256").unlink()  # a PNG odelab did not seal (planted or from before)
    assert figcache.load(figcache.figure_key(spec)) is None and not cached.exists()


def test_a_truncated_template_entry_is_compiled_again(tmp_path, monkeypatch):
    from odelab.report.render import environments

    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "cache"))
    _, md = environments()
    md.get_template("report.md.j2")
    entries = list((tmp_path / "cache" / "templates").glob("md-*/__jinja2_*.cache"))
    assert entries
    for entry in entries:
        entry.write_bytes(entry.read_bytes()[:40])
    cachedir.take_notes()
    _, md = environments()
    assert md.get_template("report.md.j2").filename.endswith("report.md.j2")
    assert any("report template" in n and "does not match its seal (damaged)" in n for n in cachedir.take_notes())


def test_planted_template_bytecode_never_runs(tmp_path, monkeypatch):
    from odelab.report.render import environments

    monkeypatch.setenv("ODELAB_CACHE_DIR", str(tmp_path / "cache"))
    _, md = environments()
    md.get_template("report.md.j2")
    marker = tmp_path / "planted-template-ran"
    code = compile(f"open({str(marker)!r}, 'w').close()\n", "planted", "exec")
    from jinja2.bccache import bc_magic

    for entry in (tmp_path / "cache" / "templates").glob("md-*/__jinja2_*.cache"):
        checksum = pickle.loads(entry.read_bytes()[len(bc_magic):])
        entry.write_bytes(bc_magic + pickle.dumps(checksum, 2) + marshal.dumps(code))
    _, md = environments()
    md.get_template("report.md.j2")  # compiled again from the template, not the planted entry
    assert not marker.exists()
