"""Regenerate (or, with ``--check``, verify) the ``*_pb2.py`` modules of this folder's ``.proto`` files.

Run from anywhere: ``python -m erforce_interfaces.ssl.ssl_proto.generate [--check]``. The generated modules
are committed, so a robot or a colcon workspace needs only the ``protobuf`` runtime, not protoc; protoc
comes from ``grpcio-tools`` (pinned with the runtime in requirements.txt). Imports between the files
use the path from the package root (``erforce_interfaces/ssl/ssl_proto/x.proto``), so the generated
modules import each other as ``erforce_interfaces.ssl.ssl_proto.x_pb2``.
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
    from grpc_tools import protoc  # a development tool: only this script needs it

    sources = [str(p.relative_to(PACKAGE_ROOT)) for p in proto_files()]
    if not sources:
        return []
    include = Path(protoc.__file__).parent / "_proto"  # protoc's well-known types
    code = protoc.main(["protoc", f"-I{PACKAGE_ROOT}", f"-I{include}", f"--python_out={out_root}", *sources])
    if code != 0:
        raise RuntimeError(f"protoc failed with exit code {code}")
    return [out_root / Path(s).with_name(Path(s).stem + "_pb2.py") for s in sources]


def stale_modules() -> list[str]:
    """Names of generated modules that differ from what protoc makes of the current .proto files."""
    with tempfile.TemporaryDirectory() as tmp:
        fresh = generate(Path(tmp))
        stale = []
        for path in fresh:
            committed = HERE / path.name
            if not committed.is_file() or committed.read_bytes() != path.read_bytes():
                stale.append(path.name)
        expected = {p.name for p in fresh}
        stale += sorted(p.name for p in HERE.glob("*_pb2.py") if p.name not in expected)
        return stale


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a generated module is out of date")
    args = parser.parse_args(argv)
    if args.check:
        stale = stale_modules()
        for name in stale:
            print(f"out of date: {name} (run python -m erforce_interfaces.ssl.ssl_proto.generate)", file=sys.stderr)
        return 1 if stale else 0
    for path in generate(PACKAGE_ROOT):
        print(path.relative_to(PACKAGE_ROOT))
    return 0


if __name__ == "__main__":
    sys.exit(main())
