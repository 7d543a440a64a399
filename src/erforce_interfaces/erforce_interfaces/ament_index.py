"""Where the stack's ROS packages live: a work-alike of ament_index_python for a venv without a ROS install.

A package is found as an importable Python package whose parent folder holds package.xml (the editable
installs of this repository) or in the ament resource index under ``AMENT_PREFIX_PATH`` (a colcon install),
as ``ros2 launch`` and ``ros2 run`` find it. Used by the contract (the DDS profile in the share folder) and
by the launcher (``$(find-pkg-share)``, executables).
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
from functools import cache
from pathlib import Path


def ament_prefixes() -> list[Path]:
    return [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]


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
    try:
        return importlib.metadata.distribution(pkg)
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return None


def _ament_prefix(pkg: str) -> Path | None:
    for prefix in ament_prefixes():
        if (prefix / "share" / "ament_index" / "resource_index" / "packages" / pkg).exists():
            return prefix
    return None


def find_package_share(pkg: str) -> Path | None:
    """share dir: 1) Python source dir with package.xml, 2) the ament index in AMENT_PREFIX_PATH."""
    source = _python_share_dir(pkg)
    if source is not None:
        return source
    prefix = _ament_prefix(pkg)
    return None if prefix is None else prefix / "share" / pkg


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
