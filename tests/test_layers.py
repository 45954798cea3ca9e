"""The layers of the package import one way only (docs/architecture.md).

Every ``import`` of every module of ``lagamine_py`` -- at the top or inside a function, relative
or absolute -- is an edge from the importing module's layer to the imported one's.  An edge to
a higher layer, or between two packages of the same layer, is a backward edge and fails the
test, as does importing a private name (``_x``) from another package.  Two behaviours the
layers exist for are checked by running them: loading a deck imports neither the solver nor
scipy, and ``lagamine-py --help`` imports neither numba, scipy nor vtk.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "lagamine_py"
DECK = Path(__file__).resolve().parents[1] / "decks" / "press_slide.dat"

#: bottom up; a module may import its own package and the layers below it
LAYERS = (
    ("core",),
    ("registry",),
    ("kernels",),
    ("model", "laws", "foundation"),
    ("elements",),
    ("deck", "output", "results"),
    ("solver", "checks"),
    ("compare", "plot", "sweep", "contracts"),
    ("cli",),
    ("__main__", "__init__"),
)
RANK = {part: rank for rank, parts in enumerate(LAYERS) for part in parts}


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).with_suffix("")
        parts = rel.parts[:-1] if rel.name == "__init__" and len(rel.parts) > 1 else rel.parts
        yield "lagamine_py." + ".".join(parts) if parts != ("__init__",) else "lagamine_py", path


def _top(module: str) -> str:
    """The layer name of a module of the package: its first component below lagamine_py."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _imports(module: str, path: Path):
    """(imported module, names, line) of every import in the file, relative ones resolved."""
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, (), node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            names = tuple(a.name for a in node.names)
            if node.module is None and node.level:       # from . import x: x may be a module
                for name in names:
                    yield f"{target}.{name}", (), node.lineno
            else:
                yield target, names, node.lineno


def _edges():
    for module, path in _modules():
        for target, names, line in _imports(module, path):
            if target == "lagamine_py" or target.startswith("lagamine_py."):
                yield module, path, target, names, line


def test_every_module_belongs_to_a_layer():
    unknown = sorted({_top(m) for m, _ in _modules()} - set(RANK))
    assert not unknown, f"modules outside every layer: {unknown}; add them to LAYERS and to " \
                        f"docs/architecture.md"


def test_no_backward_edge():
    bad = []
    for module, path, target, names, line in _edges():
        src, dst = _top(module), _top(target)
        if target == "lagamine_py":
            dst = "__init__"
        if src == dst:
            continue
        if RANK[dst] >= RANK[src]:
            bad.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {module} ({LAYERS[RANK[src]]}) "
                       f"imports {target} ({LAYERS[RANK[dst]]})")
    assert not bad, "backward or sideways imports:\n" + "\n".join(bad)


def test_no_private_name_crosses_a_package():
    bad = []
    for module, path, target, names, line in _edges():
        if _top(module) == _top(target):
            continue
        private = [n for n in names if n.startswith("_")] + \
                  [p for p in target.split(".")[1:] if p.startswith("_") and p != "__init__"]
        if private:
            bad.append(f"{path.relative_to(PACKAGE.parent)}:{line}: {module} imports {private} "
                       f"from {target}")
    assert not bad, "\n".join(bad)


def test_the_walker_sees_a_backward_edge(tmp_path, monkeypatch):
    """The test can fail: a law importing the solver is reported."""
    fake = tmp_path / "lagamine_py"
    (fake / "laws").mkdir(parents=True)
    (fake / "laws" / "bad.py").write_text("from ..solver.newton import solve_increment\n"
                                          "from ..elements.contact import _unit\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", fake)
    with pytest.raises(AssertionError, match="laws.bad"):
        test_no_backward_edge()
    with pytest.raises(AssertionError, match="_unit"):
        test_no_private_name_crosses_a_package()


def _modules_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys; print(' '.join(sys.modules))"],
                         capture_output=True, text=True, check=True).stdout
    return set(out.split())


def test_loading_a_deck_imports_neither_the_solver_nor_scipy():
    loaded = _modules_after(f"from lagamine_py.deck import load_deck; load_deck({str(DECK)!r})")
    assert "lagamine_py.deck.builder" in loaded          # it did load the deck
    assert not {m for m in loaded if m.startswith(("lagamine_py.solver", "scipy", "numba", "vtk"))}


def test_help_imports_no_heavy_library():
    loaded = _modules_after("import lagamine_py.cli as c\ntry:\n    c.main(['--help'])\n"
                            "except SystemExit:\n    pass")
    assert "lagamine_py.cli" in loaded
    assert not {m for m in loaded if m.split(".")[0] in ("numba", "scipy", "vtk", "vtkmodules",
                                                         "matplotlib")}
