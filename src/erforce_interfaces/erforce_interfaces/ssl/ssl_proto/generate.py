"""Generate (or, with ``--check``, verify) the ``*_pb2.py`` modules of this folder's ``.proto`` files.

The modules are built, not committed, as rosidl builds a ROS package's message code: ``./run setup`` and the
package's build (setup.py's ``build_py``) run ``write_modules``; by hand:
``python -m erforce_interfaces.ssl.ssl_proto.generate [--check]``. protoc comes from ``grpcio-tools`` (pinned
with the runtime in requirements.txt). Imports between the files use the path from the package root
(``erforce_interfaces/ssl/ssl_proto/x.proto``), so the generated modules import each other as
``erforce_interfaces.ssl.ssl_proto.x_pb2``. The build loads this file by its path: it imports nothing of the package.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
PACKAGE_ROOT = HERE.parents[2]  # the folder holding the erforce_interfaces package


def proto_files() -> list[Path]:
    return sorted(HERE.glob("*.proto"))


def generate(out_root: Path) -> list[Path]:
    """Run protoc on every .proto file with outputs under ``out_root``; return the generated paths."""
    from grpc_tools import protoc  # a build tool: only this script needs it

    sources = [str(p.relative_to(PACKAGE_ROOT)) for p in proto_files()]
    if not sources:
        return []
    include = Path(protoc.__file__).parent / "_proto"  # protoc's well-known types
    code = protoc.main(["protoc", f"-I{PACKAGE_ROOT}", f"-I{include}", f"--python_out={out_root}", *sources])
    if code != 0:
        raise RuntimeError(f"protoc failed with exit code {code}")
    return [out_root / Path(s).with_name(Path(s).stem + "_pb2.py") for s in sources]


def _compare(out_root: Path, fresh: list[Path]) -> tuple[list[Path], list[Path]]:
    """(fresh modules that differ from or are missing in ``out_root``, modules there without a .proto)."""
    target = out_root / HERE.relative_to(PACKAGE_ROOT)
    changed = [p for p in fresh if not (target / p.name).is_file() or (target / p.name).read_bytes() != p.read_bytes()]
    orphans = sorted(set(target.glob("*_pb2.py")) - {target / p.name for p in fresh})
    return changed, orphans


def write_modules(out_root: Path = PACKAGE_ROOT) -> list[Path]:
    """Generate the modules into the package under ``out_root`` (a build folder, or the sources for an editable
    install); rewrite only those whose bytes changed, so that their bytecode stays valid, and remove those whose
    .proto is gone. Returns the paths written."""
    target = out_root / HERE.relative_to(PACKAGE_ROOT)
    target.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        changed, orphans = _compare(out_root, generate(Path(tmp)))
        for path in changed:
            (target / path.name).write_bytes(path.read_bytes())
    for path in orphans:
        path.unlink()
    return [target / p.name for p in changed]


def stale_modules() -> list[str]:
    """Names of modules beside the .proto files that are missing, differ from what protoc makes of the current
    .proto files, or have no .proto."""
    with tempfile.TemporaryDirectory() as tmp:
        changed, orphans = _compare(PACKAGE_ROOT, generate(Path(tmp)))
        return [p.name for p in changed] + [p.name for p in orphans]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a generated module is out of date")
    args = parser.parse_args(argv)
    if args.check:
        stale = stale_modules()
        for name in stale:
            print(f"out of date: {name} (run python -m erforce_interfaces.ssl.ssl_proto.generate)", file=sys.stderr)
        return 1 if stale else 0
    for path in write_modules():
        print(path.relative_to(PACKAGE_ROOT))
    return 0


if __name__ == "__main__":
    sys.exit(main())
