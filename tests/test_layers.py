"""The one-way layers of docs/architecture.md, enforced: import-linter's contracts in pyproject.toml (every
import counts, including those inside functions), plus no import cycle between any two modules.

The cycle check reads every import statement (absolute and relative, at any depth) and resolves
``from package import name`` to the submodule when `name` is one, else to the package's ``__init__``; an
import of a package's own ``__init__`` from inside it counts like any other, so a cycle through a package
``__init__`` (the package re-exports a submodule that imports a name back from it) is found. The tests at
the bottom run the check on small synthetic packages to show that it fails on each such cycle."""
import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def lint_imports_exe() -> str:
    """Path of import-linter's `lint-imports` beside this interpreter; fails (never skips) without it: a
    missing checker must not pass as a kept contract."""
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.fail("import-linter is not installed beside this Python (pip install -e '.[test]'); the layer "
                    "contracts cannot be checked")
    return exe


def test_import_contracts_hold():
    r = subprocess.run([lint_imports_exe(), "--config", str(REPO / "pyproject.toml")], cwd=REPO,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert "broken" not in r.stdout.split("Contracts:")[-1].split(",")[0]


def module_graph(root: Path, packages=("rtchannel", "processing")) -> dict[str, set[str]]:
    """{module: the project modules it imports} for every .py file under root/<package> (a package is named
    by its ``__init__``'s dotted name)."""
    files, is_pkg = {}, {}
    for pkg in packages:
        for p in (root / pkg).rglob("*.py"):
            parts = p.relative_to(root).with_suffix("").parts
            init = parts[-1] == "__init__"
            name = ".".join(parts[:-1] if init else parts)
            files[name], is_pkg[name] = p, init

    def known(name: str) -> str | None:
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name or None

    graph = {m: set() for m in files}
    for mod, path in files.items():
        here = mod if is_pkg[mod] else mod.rpartition(".")[0]  # the package relative imports start from
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [known(a.name) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here.split(".")
                    base = base[:len(base) - (node.level - 1)]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                for a in node.names:  # a submodule, else a name defined in the package's __init__
                    sub = f"{module}.{a.name}"
                    targets.append(sub if sub in files else known(module))
            graph[mod].update(t for t in targets if t is not None and t != mod)
    return graph


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Import cycles of `graph` (depth-first search; each as [m0, m1, ..., m0])."""
    state, stack, cycles = {}, [], []

    def visit(m):
        state[m] = 1
        stack.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                cycles.append(stack[stack.index(n):] + [n])
            elif n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    return cycles


def test_no_import_cycles_between_modules():
    cycles = find_cycles(module_graph(REPO))
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles[:5])


# --- the check itself: each gap it once had fails now --------------------------------------------------------

def _tree(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return root


def test_cycle_check_sees_relative_imports(tmp_path):
    root = _tree(tmp_path, {"pkg/__init__.py": "", "pkg/a.py": "from .b import f\n",
                            "pkg/sub/__init__.py": "", "pkg/sub/c.py": "from ..a import g\n",
                            "pkg/b.py": "def f():\n    from .sub import c\n"})
    cycles = find_cycles(module_graph(root, ("pkg",)))
    assert ["pkg.a", "pkg.b", "pkg.sub.c", "pkg.a"] in cycles


def test_cycle_check_sees_cycles_through_a_package_init(tmp_path):
    # the package re-exports a module that takes a name back from the package: a partial-import error waiting
    root = _tree(tmp_path, {"pkg/__init__.py": "from pkg.core import run\nVERSION = 1\n",
                            "pkg/core.py": "from pkg import VERSION\n\ndef run():\n    return VERSION\n",
                            "pkg/ok.py": "from pkg import core\n"})
    graph = module_graph(root, ("pkg",))
    assert graph["pkg.ok"] == {"pkg.core"}  # importing a submodule through its package is no edge to __init__
    assert find_cycles(graph) == [["pkg", "pkg.core", "pkg"]]


def test_missing_import_linter_fails_instead_of_skipping(monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda *a, **k: None)
    with pytest.raises(pytest.fail.Exception, match="import-linter is not installed"):
        lint_imports_exe()
