"""The layers of the four packages, read from the imports (module level and inside functions) of every module
under src/:

- erforce_interfaces.wire (contract, conversions, robot description) imports nothing else of ours: a
  robot-side node needs only it; runtime (how a node runs) adds only the wire; ssl (the league's wire
  formats) only the wire and the runtime;
- the developer tools (erforce_interfaces.tools) are imported by the tools themselves and the demo
  (erforce_sim.demo), never by a node or a core; the test harness (tools.testing) by no module in src/ but
  its own plugin: tests and bench take it;
- erforce_ball_model and erforce_motion import nothing from the simulator; motion nothing from the ball model;
- the simulator's physics and its nodes import nothing from the ball model or motion packages: what closes
  the loop with them lives in erforce_sim.in_process (worlds in one process), erforce_sim.demo (the demo and
  its reports) and erforce_sim.view (the field view); the worlds and the view import nothing from the demo;
- no import cycle among the modules of src/;
- every import of one of our modules in src/, test/ and bench/ names a module (or a name in one) that exists.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"


def _module_name(path: Path, src: Path = SRC) -> str:
    package_root = path.relative_to(src).parts[1:]  # drop the ament package folder
    return ".".join(package_root).removesuffix(".py").removesuffix(".__init__")


def _import_froms(path: Path) -> list[tuple[str, tuple[str, ...]]]:
    """(module, names) of every absolute import in ``path``: ``import a.b`` gives ("a.b", ())."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.extend((alias.name, ()) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.module, tuple(alias.name for alias in node.names)))
    return found


def _imports(path: Path) -> set[str]:
    found = set()
    for module, names in _import_froms(path):
        found.add(module)
        found.update(f"{module}.{name}" for name in names)
    return found


def _source_files(src: Path) -> dict[str, Path]:
    return {
        _module_name(p, src): p
        for p in sorted(src.glob("*/*/**/*.py"))
        if not p.name.endswith("_pb2.py") and "setup.py" != p.name
    }


FILES = _source_files(SRC)
MODULES = {name: _imports(path) for name, path in FILES.items()}


def _is_under(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def _in(*prefixes: str):
    return lambda m: any(_is_under(m, p) for p in prefixes)


OURS = ("erforce_interfaces", "erforce_ball_model", "erforce_motion", "erforce_sim")
IFC = "erforce_interfaces"
SIM_LOOP = ("erforce_sim.in_process", "erforce_sim.demo", "erforce_sim.view")

# (rule, modules it is about, import prefixes they must not use)
RULES = [
    ("wire imports nothing else of ours", _in(f"{IFC}.wire"),
     (f"{IFC}.runtime", f"{IFC}.ssl", f"{IFC}.tools", *OURS[1:])),
    ("runtime imports only the wire", _in(f"{IFC}.runtime"), (f"{IFC}.ssl", f"{IFC}.tools", *OURS[1:])),
    ("ssl imports only wire and runtime", _in(f"{IFC}.ssl"), (f"{IFC}.tools", *OURS[1:])),
    ("the tools import no other package", _in(f"{IFC}.tools"), OURS[1:]),
    ("no module imports the test harness", lambda m: m != f"{IFC}.tools.testing", (f"{IFC}.tools.testing",)),
    ("nodes and cores import no tools", lambda m: not _in(f"{IFC}.tools", "erforce_sim.demo")(m), (f"{IFC}.tools",)),
    ("erforce_ball_model imports no simulator", _in("erforce_ball_model"), ("erforce_sim",)),
    ("erforce_motion imports no simulator or ball model", _in("erforce_motion"), ("erforce_sim", "erforce_ball_model")),
    ("erforce_sim physics and nodes", lambda m: m.startswith("erforce_sim") and not _in(*SIM_LOOP)(m),
     ("erforce_ball_model", "erforce_motion", *SIM_LOOP)),
    ("in-process worlds and the view import no demo", _in("erforce_sim.in_process", "erforce_sim.view"),
     ("erforce_sim.demo",)),
    ("the view imports no in-process world", _in("erforce_sim.view"), ("erforce_sim.in_process",)),
]


@pytest.mark.parametrize("rule", RULES, ids=[r[0] for r in RULES])
def test_layer_imports(rule):
    _, applies, forbidden = rule
    checked = [m for m in MODULES if applies(m)]
    assert checked, "the rule matches no module: the layout changed"
    offences = sorted(
        f"{module} imports {name}"
        for module in checked
        for name in MODULES[module]
        if any(_is_under(name, prefix) for prefix in forbidden)
    )
    assert not offences, "\n".join(offences)


def test_the_checker_sees_a_forbidden_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from erforce_interfaces.tools.testing import RosGraph\n"
                   "import erforce_sim.demo.demo\n")
    names = _imports(bad)
    assert any(_is_under(n, "erforce_interfaces.tools") for n in names)
    assert any(_is_under(n, "erforce_sim.demo") for n in names)
    assert not _is_under("erforce_simulation", "erforce_sim")


# --- import cycles ---------------------------------------------------------------------------------------------


def import_graph(modules: dict[str, set[str]]) -> dict[str, set[str]]:
    """Module -> the modules of ``modules`` it imports (``from a.b import c`` imports a.b, or a.b.c when that
    is a module; a package's ``__init__`` is the package's own module)."""

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    return {m: {r for name in names if (r := resolve(name)) is not None and r != m} for m, names in modules.items()}


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[v] = min(low[v], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    component.append(w)
                    if w == v:
                        break
                if len(component) > 1:
                    cycles.append(sorted(component))
    return cycles


def test_no_import_cycle_in_src():
    cycles = import_cycles(import_graph(MODULES))
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_the_cycle_finder_finds_cycles_and_only_them():
    graph = import_graph({
        "p.a": {"p.b.f"}, "p.b": {"p.c"}, "p.c": {"p.a", "os"},  # a -> b -> c -> a
        "p.d": {"p.d"}, "p.e": {"p.a", "p.f.g"}, "p.f": {"p.e"},  # self-import; f.g resolves to f: e <-> f
        "p.x": {"p.y"}, "p.y": set(),
    })
    assert graph["p.e"] == {"p.a", "p.f"}
    assert sorted(import_cycles(graph)) == [["p.a", "p.b", "p.c"], ["p.e", "p.f"]]


# --- every import of ours names something that exists ------------------------------------------------------------

EVERY_MODULE = {_module_name(p) for p in SRC.glob("*/*/**/*.py")}  # with protoc's *_pb2


@functools.cache
def _defined_in(path: Path) -> frozenset[str]:
    """Every name ``path`` binds anywhere (definitions, assignments, imports): enough to catch a name that a
    module moved away from."""
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.alias):
            names.add((node.asname or node.name).split(".")[0])
    return frozenset(names)


def _missing(module: str, names: tuple[str, ...]) -> list[str]:
    if module not in EVERY_MODULE:
        return [module]
    if module not in FILES:
        return []  # protoc's modules define their names at run time
    defined = _defined_in(FILES[module])
    return [f"{module}.{n}" for n in names if f"{module}.{n}" not in EVERY_MODULE and n not in defined]


def test_every_import_of_ours_exists():
    files = [*FILES.values(), *ROOT.glob("test/**/*.py"), *ROOT.glob("bench/**/*.py")]
    stale = sorted(
        f"{path.relative_to(ROOT)}: {name}"
        for path in files
        for module, names in _import_froms(path)
        if module.split(".")[0] in OURS
        for name in _missing(module, names)
    )
    assert not stale, "imports of modules that do not exist (a module moved?):\n" + "\n".join(stale)
