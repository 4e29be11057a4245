"""Imports point down, never up (docs/architecture.md, "The layout of `curious`").

The layers, lowest first: `suite`; then the rows of the layout table in their order (the
settings in `curious/`, `envs`, `agent`, `runs`, `watching`, `analysis`, `reproduction`); then
`pipelines`, which the command line drives; then `curious/commands/` and `curious/cli.py`. Every
import of the project's own code, at the top of a module, inside a function or for type checking
only, names a module of its own layer or of a lower one. An import inside a function is there
to keep a light module light (`curious --help`, `import suite`): the module it names loads a heavy
library that the importing module does not load already; never to hide a circle.
"""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("curious", "suite", "pipelines")
HEAVY = frozenset(
    {
        "dagster",
        "dm_control",
        "gymnasium_robotics",
        "imageio",
        "imageio_ffmpeg",
        "matplotlib",
        "mujoco",
        "pandas",
        "PIL",
        "pyarrow",
        "ray",
        "rerun",
        "scipy",
        "torch",
    }
)
"""The libraries that take long to import or pull in native code: what a light module avoids."""
WAITS_FOR_ITS_FUNCTION = HEAVY | {"tqdm"}
"""The libraries a function may import for itself: the heavy ones, and tqdm, whose `tqdm.auto`
chooses Jupyter's bars or the console's when it is imported, and warns in a notebook kernel
without ipywidgets: imported where a bar is drawn, a notebook that draws none stays quiet."""


@dataclass(frozen=True)
class Import:
    """One import of the project's own code: where it is and what it names."""

    module: str
    target: str
    line: int
    where: str  # "top", "function" or "typing"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


@cache
def _files() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _is_package(module: str) -> bool:
    return _files()[module].name == "__init__.py"


def _targets(node: ast.Import | ast.ImportFrom, module: str) -> list[str]:
    """The modules an import statement loads (`from a import b` names `a.b` where it is one)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    base = node.module or ""
    if node.level:
        here = module.split(".") if _is_package(module) else module.split(".")[:-1]
        here = here[: len(here) - node.level + 1]
        base = ".".join([*here, base] if base else here)
    found = [f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in _files()]
    return found or [base]


@cache
def _imports(module: str) -> tuple[tuple[str, str, int], ...]:
    """(target, where, line) for every import statement of `module`, third-party ones too."""
    tree = ast.parse(_files()[module].read_text())
    out: list[tuple[str, str, int]] = []

    def visit(node: ast.AST, where: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                out.extend((t, where, child.lineno) for t in _targets(child, module))
            elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                visit(child, "function" if where == "top" else where)
            elif isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                visit(child, "typing")
            else:
                visit(child, where)

    visit(tree, "top")
    return tuple(out)


def _own(target: str) -> str | None:
    """The project module an import names (the longest known prefix), or None if third-party."""
    if target.split(".")[0] not in PACKAGES:
        return None
    parts = target.split(".")
    while parts and ".".join(parts) not in _files():
        parts.pop()
    return ".".join(parts) if parts else None


def own_imports() -> list[Import]:
    found = []
    for module in _files():
        for target, where, line in _imports(module):
            own = _own(target)
            if own is not None and own != module:
                found.append(Import(module, own, line, where))
    return found


@cache
def _heavy(module: str) -> frozenset[str]:
    """The heavy libraries importing `module` loads: those its top-level imports name, those of
    the project's modules they load (with their packages' `__init__`), transitively."""
    seen: set[str] = set()
    heavy: set[str] = set()
    todo = [module]
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        parts = current.split(".")
        todo.extend(".".join(parts[:i]) for i in range(1, len(parts)))  # parent packages
        for target, where, _ in _imports(current):
            if where != "top":
                continue
            own = _own(target)
            if own is None:
                if target.split(".")[0] in HEAVY:
                    heavy.add(target.split(".")[0])
            else:
                todo.append(own)
    return frozenset(heavy)


def layers() -> list[tuple[str, ...]]:
    """The layers, lowest first, as path prefixes (`curious/runs/`) or files (`curious/gl.py`)."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    section = text.split("## The layout of `curious`", 1)[1].split("\n## ", 1)[0]
    rows: list[tuple[str, ...]] = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 3 or not cells[0].startswith("`curious/"):
            continue
        where = cells[0].strip("`")
        if where == "curious/":  # the top-level modules the row lists
            names = re.findall(r"`(\w+\.py)`", cells[2])
            rows.append(tuple(f"curious/{n}" for n in names))
        else:
            rows.append((where,))
    commands = next(i for i, row in enumerate(rows) if row == ("curious/commands/",))
    return [("suite/",), *rows[:commands], ("pipelines/",), *rows[commands:]]


def layer_of(module: str) -> int:
    path = _files()[module].relative_to(ROOT).as_posix()
    if path == "curious/__init__.py":
        return -1  # the package itself, which every module's import runs first
    for index, row in enumerate(layers()):
        if any(path == p or (p.endswith("/") and path.startswith(p)) for p in row):
            return index
    raise AssertionError(f"{path} is in no layer of docs/architecture.md's layout table")


def test_every_module_lies_in_one_layer():
    for module in _files():
        layer_of(module)


def test_imports_point_down_never_up():
    upward = [
        f"{i.module}:{i.line} ({i.where}) imports {i.target}"
        for i in own_imports()
        if layer_of(i.target) > layer_of(i.module) and layer_of(i.module) != -1
    ]
    assert not upward, "imports pointing up the layers:\n" + "\n".join(upward)


def test_no_module_imports_itself_through_others():
    """No circle at all, within a layer too: following the imports (at the top, in functions or
    for type checking) from any module never leads back to it."""
    graph: dict[str, set[str]] = {}
    for i in own_imports():
        graph.setdefault(i.module, set()).add(i.target)
    done: set[str] = set()

    def walk(module: str, path: list[str]) -> None:
        if module in path:
            raise AssertionError(
                "import circle: " + " -> ".join([*path[path.index(module) :], module])
            )
        if module in done:
            return
        for target in sorted(graph.get(module, ())):
            walk(target, [*path, module])
        done.add(module)

    for module in sorted(graph):
        walk(module, [])


def test_an_import_inside_a_function_keeps_its_module_light():
    hidden = [
        f"{i.module}:{i.line} imports {i.target} inside a function, and it loads nothing "
        f"heavier than {i.module} (move it to the top)"
        for i in own_imports()
        if i.where == "function" and not _heavy(i.target) - _heavy(i.module)
    ]
    assert not hidden, "\n".join(hidden)


def test_a_library_imported_inside_a_function_is_a_heavy_one():
    """The standard library, numpy and the like are imported at the top: only a library that
    takes long to load (or tqdm, above), and that the module does not load already, waits for
    its function."""
    hidden = [
        f"{module}:{line} imports {target} inside a function (move it to the top)"
        for module in _files()
        for target, where, line in _imports(module)
        if where == "function"
        and _own(target) is None
        and (
            target.split(".")[0] not in WAITS_FOR_ITS_FUNCTION
            or target.split(".")[0] in _heavy(module)
        )
    ]
    assert not hidden, "\n".join(hidden)


def test_no_module_level_getattr():
    """A package's names are imported plainly, so that go-to-definition finds them."""
    lazy = [
        m
        for m, path in _files().items()
        if any(
            isinstance(n, ast.FunctionDef) and n.name == "__getattr__"
            for n in ast.parse(path.read_text()).body
        )
    ]
    assert not lazy, f"module-level __getattr__ in {lazy}"


@pytest.mark.parametrize(
    ("module", "light"),
    [("curious.config", True), ("curious.agent.learner", False)],
)
def test_the_weight_rule_reads_what_a_module_loads(module, light):
    """The rule's own check: the settings load no heavy library, the learner loads torch."""
    assert (not _heavy(module)) is light, _heavy(module)


def test_the_analysis_package_holds_its_modules_public_names():
    """`from curious import analysis; analysis.load_tests(...)`: the package imports every name of
    the `__all__` of each module it names, and nothing else is public."""
    import importlib

    import curious.analysis as analysis

    tree = ast.parse(_files()["curious.analysis"].read_text())
    sources = [n.module for n in tree.body if isinstance(n, ast.ImportFrom) and n.module]
    public = [m for m in sources if m.startswith("curious.analysis.")]
    assert len(public) >= 10, public
    names: set[str] = set()
    for source in public:
        module = importlib.import_module(source)
        for name in module.__all__:
            assert getattr(analysis, name) is getattr(module, name), (source, name)
        names |= set(module.__all__)
    assert set(analysis.__all__) == names
