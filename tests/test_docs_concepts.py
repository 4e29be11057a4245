"""docs/architecture.md's table from the paper's concepts to the code names real places: every
file and every `Class.method` or function it names exists, where the row says it lives."""

import ast
import importlib
import re
from pathlib import Path

import pytest

from curious.config import Config

ROOT = Path(__file__).resolve().parents[1]
CONCEPTS = (
    "E-UVFA input",
    "competence",
    "LP and p_LP",
    "task selection",
    "task replay",
    "HER relabelling",
    "reward recomputation",
    "the update",
    "MG-TE",
    "the flat baseline",
    "the sensory failure",
)


def _rows() -> dict[str, list[str]]:
    text = (ROOT / "docs" / "architecture.md").read_text()
    section = text.split("## Where the paper lives in the code", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0] not in ("concept", "---"):
            rows[cells[0]] = cells
    return rows


def _top_level(path: Path) -> set[str]:
    """The classes and functions a source file defines at its top level."""
    body = ast.parse(path.read_text()).body
    return {n.name for n in body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}


def _resolve(name: str, homes: dict[str, str]) -> object:
    """The object `Head` or `Head.attr` names (Head: a class or function of `homes`)."""
    head, _, attr = name.partition(".")
    obj = getattr(importlib.import_module(homes[head]), head)
    return getattr(obj, attr) if attr else obj


def test_every_concept_of_the_paper_has_a_row():
    rows = _rows()
    for concept in CONCEPTS:
        assert any(name.startswith(concept) for name in rows), concept


def test_every_place_the_table_names_exists_where_it_says(monkeypatch: pytest.MonkeyPatch):
    # The names resolve by importing their modules, dm_control's among them: without GL, as
    # every command but `curious render` runs (`curious.gl`), not GLFW on a headless machine.
    monkeypatch.setenv("MUJOCO_GL", "disable")
    homes = {}
    for path in [*ROOT.glob("curious/**/*.py"), *ROOT.glob("suite/*.py")]:
        module = path.relative_to(ROOT).with_suffix("").as_posix().replace("/", ".")
        for name in _top_level(path):
            homes.setdefault(name, module)
    for concept, (_, where, called_from) in _rows().items():
        files = re.findall(r"`((?:curious|suite)/[\w/]+\.py)`", where)
        assert files, concept
        own = set().union(*(_top_level(ROOT / f) for f in files))
        names = re.findall(r"`([A-Za-z_]\w*(?:\.\w+)?)`", where)
        assert {n.split(".")[0] for n in names} & own, (concept, "names nothing of", files)
        named_classes = [n.split(".")[0] for n in names if n.split(".")[0] in homes]
        for name in names + re.findall(r"`([A-Za-z_]\w*\.\w+)`", called_from):
            if name.split(".")[0] in homes:
                assert _resolve(name, homes) is not None, (concept, name)
            else:  # a method named bare after its class (`encode_pair`), or a setting
                owners = [_resolve(c, homes) for c in named_classes] + [Config]
                assert any(hasattr(o, name) for o in owners), (concept, name)


def _modules(package: str) -> set[str]:
    """The module files of a package, relative to it (`recording/recorder.py`), without
    `__init__.py`."""
    base = ROOT / package
    return {p.relative_to(base).as_posix() for p in base.rglob("*.py") if p.name != "__init__.py"}


def test_no_two_modules_share_a_name():
    """One name, one module: a reader who meets `trainer` or `folder` knows which file it is.
    Sub-commands are named after their command (`curious/commands/train.py`), so they may
    share a name with the module that does the work."""
    seen: dict[str, str] = {}
    for package in ("curious", "suite", "pipelines"):
        for relative in sorted(_modules(package)):
            path = f"{package}/{relative}"
            if path.startswith("curious/commands/"):
                continue
            name = Path(relative).name
            assert name not in seen, f"{path} and {seen[name]} share the name {name}"
            seen[name] = path


def _layout_rows() -> dict[str, str]:
    text = (ROOT / "docs" / "architecture.md").read_text()
    section = text.split("## The layout of `curious`", 1)[1].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0].startswith("`curious/"):
            rows[cells[0].strip("`")] = cells[2]
    return rows


def test_the_layout_table_lists_every_module_where_it_lies():
    rows = _layout_rows()
    listed = set()
    for package, modules in rows.items():
        if package.endswith(".py"):  # a row of one module (`curious/cli.py`)
            assert (ROOT / package).is_file(), f"{package} is in the table, not on disk"
            listed.add(package)
            continue
        names = re.findall(r"`([\w/]+\.py)`", modules)
        subfolders = re.findall(r"`(\w+)/`", modules)
        for name in names:
            owner = next(
                (f"{package}{s}/" for s in subfolders if (ROOT / package / s / name).exists()),
                package,
            )
            assert (ROOT / owner / name).is_file(), f"{owner}{name} is in the table, not on disk"
            listed.add(f"{owner}{name}")
    on_disk = {
        f"curious/{m}"
        for m in _modules("curious")
        if not m.startswith("analysis/figures/")  # the figures are listed as `figures/`
    }
    assert on_disk == listed, (
        f"missing {sorted(on_disk - listed)}, stale {sorted(listed - on_disk)}"
    )
