"""The codebase's own promises, checked by reading it: layers that import only downwards,
small modules, kernels with named arguments, citations that resolve, a user's README, and no
warning filters in the way of a user's own test run (tests/test_scenes.py runs one, checking
for SyntaxWarnings)."""

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "tai_coll"
MAX_MODULE_LINES = 600
MAX_KERNEL_PARAMETERS = 24


def modules() -> dict:
    """Every module of tai_coll: dotted name -> path."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def imports_of(name: str, path: Path, known: dict) -> set:
    """The tai_coll modules `name` imports, anywhere in the file (functions included)."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                stem = ".".join(base + ([node.module] if node.module else []))
            else:
                stem = node.module
            # `from pkg import module` names a module; `from module import name` the module itself
            targets = [f"{stem}.{alias.name}" if f"{stem}.{alias.name}" in known else stem for alias in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target.startswith("tai_coll") and target != name:
                out.add(target)
    return out


def cycles(graph: dict) -> list:
    """The strongly connected components with more than one node (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def package_of(module: str) -> str:
    """tai_coll.geometry.kinds -> tai_coll.geometry; top-level modules are their own layer."""
    parts = module.split(".")
    return ".".join(parts[:2])


def test_no_module_imports_a_module_that_imports_it_back():
    # Every import counts, also those inside functions: a lazy import hiding a cycle is a cycle.
    known = modules()
    graph = {name: imports_of(name, path, known) for name, path in known.items()}
    # a package's __init__ re-exports its modules: an edge from the package to its own modules
    # is not a layer going up
    for name in graph:
        graph[name] = {t for t in graph[name] if not t.startswith(name + ".")}
    assert cycles(graph) == []


def test_packages_import_each_other_in_one_direction_only():
    known = modules()
    graph = {}
    for name, path in known.items():
        for target in imports_of(name, path, known):
            a, b = package_of(name), package_of(target)
            if a != b and not (name == "tai_coll"):  # the facade imports every layer
                graph.setdefault(a, set()).add(b)
    assert cycles(graph) == [], graph


def test_the_bottom_module_imports_no_layer_above_it():
    known = modules()
    assert imports_of("tai_coll.types", known["tai_coll.types"], known) <= {"tai_coll.runtime"}
    assert imports_of("tai_coll.sorting", known["tai_coll.sorting"], known) == set()


def test_solvers_do_not_read_a_scene_or_import_it():
    for path in (PACKAGE / "solvers").rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"scene\._\w+", text), path
        assert "from ..scene" not in text and "from ...scene" not in text, path
    scene = (PACKAGE / "scene" / "scene.py").read_text()
    assert "hasattr(" not in scene and "getattr(self.solver" not in scene


def test_no_module_is_longer_than_600_lines():
    long = {str(p.relative_to(ROOT)): n for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert long == {}


def test_kernels_take_their_arrays_in_named_packs():
    # No kernel back at 40 positional arguments: a kernel's arrays come in argument packs
    # (types.py), its settings as named parameters.
    wide = {}
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and any(
                    ast.unparse(d).endswith("ti.kernel") for d in node.decorator_list):
                count = len(node.args.args) + len(node.args.kwonlyargs)
                if count > MAX_KERNEL_PARAMETERS:
                    wide[f"{path.name}:{node.name}"] = count
    assert wide == {}


def test_every_physics_citation_resolves_in_the_repository():
    physics = (ROOT / "docs" / "physics.md").read_text()
    sections = set(re.findall(r"^## (\d+)\. ", physics, flags=re.M))
    assert sections >= {"1", "2", "3", "4", "5", "6"}
    cited = set()
    for folder in ("tai_coll", "tools", "scenes", "tests"):
        for path in (ROOT / folder).rglob("*.py"):
            text = path.read_text()
            assert "PHYSICS" + ".md" not in text, path  # the notes outside the repository
            cited |= set(re.findall(r"docs/physics\.md (\d+)", text))
    assert cited and cited <= sections, cited - sections


def test_readme_is_a_users_guide():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 300
    assert "bash tools/setup.sh && .venv/bin/python -m pytest -q" in readme
    assert "bash tools/setup.sh && .venv/bin/tai-coll run" in readme
    assert not re.search(r"tried and not kept|this session|last session|issue \d", readme, flags=re.I)
    for page in ("physics.md", "api.md", "benchmarks.md", "design-notes.md"):
        assert f"docs/{page}" in readme and (ROOT / "docs" / page).is_file(), page
    assert ".venv/bin/python -m pytest -q" in (ROOT / ".ci" / "run").read_text()


def test_pyproject_hides_no_warnings():
    assert "filterwarnings" not in (ROOT / "pyproject.toml").read_text()


def test_the_readmes_scene_runs_clean():
    # The README's first scene, as a user pastes it: no particle starts inside a collider,
    # none needs the failsafe, none is lost, and they come to rest on the floor.
    readme = (ROOT / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", readme, flags=re.S).group(1)
    code = code.replace('tc.init(arch="cpu")', "pass")  # the session's runtime (conftest)
    namespace = {}
    exec(compile(code, "README.md", "exec"), namespace)
    scene = namespace["scene"]
    stats = scene.stats()
    assert {name: stats[name] for name in ("failsafe", "repulsion", "non_finite", "left_domain")} == dict.fromkeys(
        ("failsafe", "repulsion", "non_finite", "left_domain"), 0)
    x = scene.positions()
    assert x[:, 1].min() > 0.005 * (1 - 1e-3)  # on or above the floor
