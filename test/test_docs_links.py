"""Every file path, module and command the markdown docs name exists.

README.md, docs/*.md and docs/decisions/*.md name files (`src/erforce_sim/launch/demo.launch.yaml`,
`erforce_sim/kicker.py`), modules and their members (`erforce_interfaces.tools.docs`,
`lockstep.DutyGate`), links and console scripts. A rename that forgets a doc leaves a newcomer with a
path that is not there; this test reads the docs and the source tree as text (no imports, no DDS) and
names each token that resolves to nothing.
"""

import ast
import re
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "docs/decisions").glob("*.md"))]
PACKAGES = ("erforce_interfaces", "erforce_ball_model", "erforce_motion", "erforce_sim")
SOURCE_SUFFIXES = (".py", ".yaml", ".yml", ".md", ".xml", ".json", ".toml", ".proto", ".cfg", ".txt", ".sh")
# Files the docs name that a run writes or a user brings, not files of the repository.
NOT_IN_REPO = {"summary.md", "grsim_robot.yaml", "fit.png", "passes.png", "requirements-lock.txt"}
# Names of other projects the docs quote (sros2, ros2/launch), and a placeholder.
NOT_OURS = {"KEYSTORE", "create_keystore", "create_enclave", "append_env", "reset_env",
            "assert_entity_completely_parsed"}
IDENTIFIER = re.compile(r"[A-Z][A-Z0-9_]{3,}|[a-z][a-z0-9]*(_[a-z0-9]+)+")  # a constant, a parameter, a function
CODE_SPAN = re.compile(r"`([^`\n]+)`")
FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)
INDENTED = re.compile(r"^ {4}(\S.*)$", re.M)  # an indented code block's line (the decision records' commands)
LINK = re.compile(r"\]\(([^)\s#]+)(?:#[^)]*)?\)")
PATH_WORD = re.compile(r"^\.?[A-Za-z0-9_][\w.\-]*(/[\w.\-]+)*/?$")
DOTTED = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)+$")


def _tracked_paths():
    files = [p.relative_to(ROOT).as_posix() for p in ROOT.rglob("*")
             if p.is_file() and not any(part.startswith(".") or part in ("__pycache__", "report", "figures")
                                        or part.endswith(".egg-info") for part in p.relative_to(ROOT).parts)]
    dirs = {Path(f).parent.as_posix() for f in files}
    dirs |= {Path(d).parent.as_posix() for d in list(dirs)}
    return set(files), {d for d in dirs if d != "."}


FILES, DIRS = _tracked_paths()


def _words(spans):
    """Each whitespace-separated word of code spans or blocks, trimmed of punctuation."""
    for span in spans:
        for word in span.split():
            word = word.strip("()[],;:'\"").removesuffix("...")
            word = re.sub(r"\(.*$", "", word)  # `World.kick(angle_deg=...)`: the name before the call
            if word and not any(c in word for c in "<>$*{}=@"):
                yield word


def _resolves_as_path(word, doc):
    if word in NOT_IN_REPO:
        return True
    rel = word.removeprefix("./").rstrip("/")
    if (doc.parent / rel).exists() or (ROOT / rel).exists():
        return True
    if word.endswith("/"):
        return any(d == rel or d.endswith("/" + rel) for d in DIRS)
    return any(f == rel or f.endswith("/" + rel) for f in FILES | DIRS)


def _is_path(word):
    if word.startswith("/") or "://" in word or not PATH_WORD.match(word) or re.fullmatch(r"[\d/]+", word):
        return False  # topics, URLs, absolute paths of a user's machine, port pairs
    if word.startswith(".") and "/" not in word:
        return False  # a file type (`.proto`)
    if word.startswith(("report/", "figures/", "tmp/")):
        return False  # written by a run
    if "/msg/" in word or "_msgs/" in word:
        return False  # a message type
    return word.endswith(SOURCE_SUFFIXES) or "/" in word


@cache
def _module_files():
    """Every module and package of ours by its dotted name."""
    by_dotted = {}
    for pkg in PACKAGES:
        for path in (ROOT / "src" / pkg / pkg).rglob("*.py"):
            parts = path.relative_to(ROOT / "src" / pkg).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            by_dotted[".".join(parts)] = path
    return by_dotted


@cache
def _names(path):
    """Top-level names of a module and the members of its classes (class name -> member names)."""
    tree = ast.parse(path.read_text())
    top, members = set(), {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            top.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            top |= {n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)}
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            top |= {(a.asname or a.name).split(".")[0] for a in node.names}
        if isinstance(node, ast.ClassDef):
            names = set()
            for item in ast.walk(node):
                if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                    names.add(item.name)
                elif isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    names.add(item.target.id)
                elif isinstance(item, ast.Assign):
                    names |= {n.id for t in item.targets for n in ast.walk(t) if isinstance(n, ast.Name)}
                elif isinstance(item, ast.Attribute) and isinstance(item.ctx, ast.Store):
                    names.add(item.attr)
            members[node.name] = names
    return top, members


def _resolves_in(module, rest):
    """`rest` (a list of names) is a submodule chain then at most a top-level name and one member."""
    by_dotted = _module_files()
    while rest and f"{module}.{rest[0]}" in by_dotted:
        module, rest = f"{module}.{rest[0]}", rest[1:]
    if not rest:
        return True
    top, members = _names(by_dotted[module])
    if rest[0] not in top:
        return False
    return len(rest) == 1 or rest[0] not in members or rest[1] in members[rest[0]] or len(rest) > 2


def _resolves_as_module(word):
    """None when the word names nothing of ours; else whether what it names exists."""
    by_dotted = _module_files()
    parts = word.split(".")
    if parts[0] in PACKAGES:
        for i in range(len(parts), 0, -1):
            if ".".join(parts[:i]) in by_dotted:
                return _resolves_in(".".join(parts[:i]), parts[i:])
        return False
    classes = [members[parts[0]] for path in by_dotted.values() for members in [_names(path)[1]]
               if parts[0] in members]
    if classes and len(parts) == 2:  # `Class.member` of a class of ours
        return any(parts[1] in members for members in classes)
    for i in range(len(parts) - 1, 0, -1):
        candidates = [m for m in by_dotted if m.endswith("." + ".".join(parts[:i]))]
        if candidates:
            return any(_resolves_in(m, parts[i:]) for m in candidates)
    return None


@cache
def _source_text():
    """Everything a name of ours can be spelled in: sources, schemas, launch files, benches, tests, ./run."""
    paths = [p for d in ("src", "bench", "test") for p in (ROOT / d).rglob("*")
             if p.is_file() and p.suffix in (".py", ".cfg", ".yaml", ".xml", ".json") and "__pycache__" not in p.parts
             and p != Path(__file__).resolve()]
    return "\n".join([p.read_text() for p in paths] + [p.stem for p in paths] + [(ROOT / "run").read_text()])


def _console_scripts():
    scripts = set()
    for setup in (ROOT / "src").glob("*/setup.cfg"):
        scripts |= set(re.findall(r"^\s*([\w-]+)\s*=\s*[\w.]+:\w+\s*$", setup.read_text(), re.MULTILINE))
    return scripts


# the program behind a command line, for its `--options`: a bench script, or the demo
PROGRAMS = {r"(bench/\w+\.py)": None, r"^\./run demo\b": "src/erforce_sim/erforce_sim/demo/demo.py"}


def _unknown_options(lines):
    """`--option`s on a line that runs a bench script or the demo which that program's source never spells."""
    missing = []
    for line in lines:
        for pattern, program in PROGRAMS.items():
            found = re.search(pattern, line)
            if not found:
                continue
            source = (ROOT / (program or found.group(1))).read_text()
            if "bench_main" in source:  # bench/table.py's shared command line: --quick
                source += (ROOT / "bench/table.py").read_text()
            command = re.sub(r"\"[^\"]*\"", "", line.split("#")[0])  # not a quoted launch argument's options
            for option in re.findall(r"(?<![\w-])--[a-z][\w-]*", command):
                negated = option.startswith("--no-") and "BooleanOptionalAction" in source  # argparse's --no-X
                if f'"{option}"' not in source and not (negated and f'"--{option[5:]}"' in source):
                    missing.append(f"option {option} of {program or found.group(1)}")
    return missing


def _unresolved(doc):
    text = doc.read_text()
    missing = []
    for target in LINK.findall(text):
        if "://" not in target and not (doc.parent / target).exists():
            missing.append(f"link {target}")
    blocks = FENCE.findall(text) + INDENTED.findall(FENCE.sub("", text))
    inline = CODE_SPAN.findall(FENCE.sub("", text))
    for word in _words(inline + blocks):
        if _is_path(word) and not _resolves_as_path(word, doc):
            missing.append(f"path {word}")
    # dotted names in prose; in code blocks a dotted name is mostly a variable's attribute (`ball.within`)
    for word in _words(inline):
        if not _is_path(word) and DOTTED.match(word) and _resolves_as_module(word) is False:
            missing.append(f"name {word}")
    for word in set(_words(inline)):  # `clock_jump_s`, `STANDBY_FIRST_S`: a parameter or constant still spelled so
        if IDENTIFIER.fullmatch(word) and word not in NOT_OURS and word not in _source_text():
            missing.append(f"identifier {word}")
    for block in blocks:
        for module, names in re.findall(r"^from ([\w.]+) import (.+)$", block, re.M):
            for name in names.split(","):
                if _resolves_as_module(f"{module}.{name.strip()}") is False:
                    missing.append(f"name {module}.{name.strip()}")
    missing += _unknown_options(inline + [line for block in blocks for line in block.splitlines()])
    scripts = _console_scripts()
    for block in blocks:
        for line in block.splitlines():
            command = re.sub(r"^(\w+=\S+\s+)+", "", line.strip())
            command = re.sub(r"^(\./run exec|\.venv/bin/)\s*", "", command).split(" ")[0]
            if re.fullmatch(r"(erforce[-_]\w[\w-]*|ssl_\w+|ball_\w+|\w+_(node|bridge|predictor|view|log))", command):
                if command not in scripts:
                    missing.append(f"command {command}")
    return missing


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_named_path_module_and_command_exists(doc):
    assert _unresolved(doc) == []


def test_the_check_finds_what_is_not_there(tmp_path):
    doc = tmp_path / "x.md"
    doc.write_text(
        "`erforce_sim/catcher.py` `erforce_sim/world.py` `erforce_interfaces.tools.docs` "
        "`erforce_interfaces.tools.nodoc` `lockstep.DutyGate` `lockstep.NoGate` [a](missing.md) `.proto`\n"
        "`World.kick` `World.nokick` `./run demo --world ssl --no-such-option` `clock_jump_s` `no_such_param_s`\n"
        "```sh\nerforce-launch x\nerforce-nolaunch x\n```\n"
        "```python\nfrom erforce_ball_model.ball_model import BallTrajectory, NoTrajectory\nball.nothing\n```\n")
    assert _unresolved(doc) == [
        "link missing.md", "path erforce_sim/catcher.py", "name erforce_interfaces.tools.nodoc",
        "name lockstep.NoGate", "name World.nokick", "identifier no_such_param_s",
        "name erforce_ball_model.ball_model.NoTrajectory",
        "option --no-such-option of src/erforce_sim/erforce_sim/demo/demo.py", "command erforce-nolaunch"]
