"""The layers of the four packages, read from the imports of every module under src/.

- the wire contract, conversions and node helpers of erforce_interfaces import none of its developer tools
  (erforce_interfaces.tools) and none of the other packages;
- erforce_ball_model and erforce_motion import nothing from the simulator or the tools;
- the simulator's physics and its plant import nothing from the ball model or motion packages: what closes
  the loop with them lives in erforce_sim.closed_loop.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"


def _module_name(path: Path) -> str:
    package_root = path.relative_to(SRC).parts[1:]  # drop the ament package folder
    return ".".join(package_root).removesuffix(".py").removesuffix(".__init__")


def _imports(path: Path) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return found


MODULES = {
    _module_name(p): _imports(p)
    for p in sorted(SRC.glob("*/*/**/*.py"))
    if not p.name.endswith("_pb2.py") and "setup.py" != p.name
}

# (modules this rule is about, import prefixes they must not use)
RULES = [
    ("erforce_interfaces (not tools)", lambda m: m.startswith("erforce_interfaces") and ".tools" not in m,
     ("erforce_interfaces.tools", "erforce_ball_model", "erforce_motion", "erforce_sim")),
    ("erforce_ball_model", lambda m: m.startswith("erforce_ball_model"), ("erforce_sim", "erforce_interfaces.tools")),
    ("erforce_motion", lambda m: m.startswith("erforce_motion"),
     ("erforce_sim", "erforce_ball_model", "erforce_interfaces.tools")),
    ("erforce_sim physics and plant", lambda m: m.startswith("erforce_sim") and ".closed_loop" not in m,
     ("erforce_ball_model", "erforce_motion", "erforce_sim.closed_loop", "erforce_interfaces.tools")),
]


def _is_under(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


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
    bad.write_text("from erforce_interfaces.tools.launcher import main\nimport erforce_sim.demo.demo\n")
    names = _imports(bad)
    assert any(_is_under(n, "erforce_interfaces.tools") for n in names)
    assert any(_is_under(n, "erforce_sim.closed_loop") for n in names)
    assert not _is_under("erforce_simulation", "erforce_sim")
