"""Where the stack's ROS packages live, and how ``./run setup`` registers them.

Lookup, a work-alike of ament_index_python: a package is found in the ament resource index under
``AMENT_PREFIX_PATH`` first (what ``./run setup`` installs into .venv, or a colcon install), as
``ros2 launch`` and ``ros2 run`` find it, then in the running interpreter's prefix (the .venv, also when
the environment does not name it); else as an importable Python package whose parent folder holds
package.xml (an editable install without the index). Used by the contract (the DDS profile in the share
folder) and by the launcher (``$(find-pkg-share)``, executables).

Registration (``python -m erforce_interfaces.wire.ament_index PREFIX PACKAGE_DIR...``, run by ``./run setup``):
what ``colcon build --symlink-install`` puts into an install prefix for an ament_python package, read
from its setup.py and setup.cfg: the ``data_files`` (the index marker, package.xml, launch, config, params) as
symlinks to the sources, so edits take effect without reinstalling, and ``lib/<pkg>/<exe>`` for every
console script.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import importlib.metadata

# importlib.metadata (with email, zipfile, ...) is imported where it is used: every node imports this module
# through the contract, and at each (re)start that import was ~0.1 s of CPU no node needs.

INDEX_MARKERS = Path("share/ament_index/resource_index/packages")


def ament_prefixes() -> list[Path]:
    """AMENT_PREFIX_PATH's prefixes, then this interpreter's own prefix where it holds an ament index (the
    .venv that ./run setup registers the packages in): a tool run as ``.venv/bin/python`` or
    ``.venv/bin/erforce-launch`` without ``./run exec`` finds the packages, their executables and
    ``$(find-pkg-prefix)`` where ``./run exec`` finds them, as a colcon install's Python finds its own."""
    prefixes = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    own = Path(sys.prefix)
    if own not in prefixes and (own / INDEX_MARKERS).is_dir():
        prefixes.append(own)
    return prefixes


@cache
def _python_share_dir(pkg: str) -> Path | None:
    """An importable Python package whose parent directory holds package.xml (our editable installs)."""
    if not pkg.isidentifier():
        return None
    try:
        spec = importlib.util.find_spec(pkg)
    except (ImportError, ValueError):
        return None
    for location in (spec.submodule_search_locations or []) if spec else []:
        source_dir = Path(location).parent
        if (source_dir / "package.xml").is_file():
            return source_dir
    return None


@cache
def distribution(pkg: str) -> importlib.metadata.Distribution | None:
    import importlib.metadata

    try:
        return importlib.metadata.distribution(pkg)
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return None


def _ament_prefix(pkg: str) -> Path | None:
    for prefix in ament_prefixes():
        if (prefix / INDEX_MARKERS / pkg).exists():
            return prefix
    return None


def find_package_share(pkg: str) -> Path | None:
    """share dir: 1) the ament index in AMENT_PREFIX_PATH, 2) Python source dir with package.xml."""
    prefix = _ament_prefix(pkg)
    return _python_share_dir(pkg) if prefix is None else prefix / "share" / pkg


def find_package_prefix(pkg: str) -> Path | None:
    """The ament prefix; a source-only package counts as its own prefix (a deviation)."""
    return _ament_prefix(pkg) or _python_share_dir(pkg)


def console_scripts(pkg: str) -> dict[str, importlib.metadata.EntryPoint]:
    dist = distribution(pkg)
    if dist is None:
        return {}
    return {ep.name: ep for ep in dist.entry_points if ep.group == "console_scripts"}


def package_executables(pkg: str) -> list[str]:
    names = set(console_scripts(pkg))
    for prefix in ament_prefixes():
        lib = prefix / "lib" / pkg
        if lib.is_dir():
            names.update(p.name for p in lib.iterdir() if p.is_file() and os.access(p, os.X_OK))
    return sorted(names)


# ================================================================== registration
@dataclass(frozen=True)
class SetupInfo:
    """What registration needs of a package's setup.py."""

    name: str
    data_files: list[tuple[str, list[str]]]  # (destination folder in the prefix, files relative to the package)
    console_scripts: list[importlib.metadata.EntryPoint]


def read_setup(package_dir: Path) -> SetupInfo:
    """Run ``package_dir/setup.py`` up to its configuration, setup.cfg read (no build); the globs are relative
    to the package."""
    from distutils.core import run_setup  # setuptools' copy

    cwd = Path.cwd()
    os.chdir(package_dir)
    try:
        dist = run_setup("setup.py", stop_after="config")
    finally:
        os.chdir(cwd)
    import importlib.metadata

    scripts = [importlib.metadata.EntryPoint(*(part.strip() for part in spec.split("=", 1)), "console_scripts")
               for spec in (dist.entry_points or {}).get("console_scripts", [])]
    data_files = [(dest, list(files)) for dest, files in dist.data_files or []]
    return SetupInfo(dist.get_name(), data_files, scripts)


def _script_text(script: importlib.metadata.EntryPoint) -> str:
    top = script.attr.split(".")[0]
    return (f"#!{sys.executable}\n"
            f"# {script.name}: console script of {script.module} (its package's setup.py)\n"
            f"import sys\n\nfrom {script.module} import {top}\n\n"
            f"if __name__ == \"__main__\":\n    sys.exit({script.attr}())\n")


def register_package(prefix: Path, package_dir: Path) -> SetupInfo:
    """Install ``package_dir``'s index entries into ``prefix``, replacing what an earlier run put there."""
    package_dir = package_dir.resolve()
    info = read_setup(package_dir)
    pkg = info.name
    for stale in (prefix / "share" / pkg, prefix / "lib" / pkg):
        if stale.is_symlink() or stale.is_file():
            stale.unlink()
        elif stale.is_dir():
            shutil.rmtree(stale)
    for dest, files in info.data_files:
        folder = prefix / dest
        folder.mkdir(parents=True, exist_ok=True)
        for name in files:
            link = folder / Path(name).name
            if link.is_symlink() or link.exists():
                link.unlink()
            link.symlink_to(package_dir / name)
    lib = prefix / "lib" / pkg
    lib.mkdir(parents=True, exist_ok=True)
    for script in info.console_scripts:
        path = lib / script.name
        path.write_text(_script_text(script))
        path.chmod(0o755)
    return info


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m erforce_interfaces.wire.ament_index",
                                     description="Register ament_python packages in the ament index of a prefix.")
    parser.add_argument("prefix", type=Path, help="install prefix (the venv)")
    parser.add_argument("packages", type=Path, nargs="+", help="package folders (with setup.py)")
    args = parser.parse_args(argv)
    for package_dir in args.packages:
        info = register_package(args.prefix, package_dir)
        print(f"[setup] ament index: {info.name} ({len(info.console_scripts)} executables)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
