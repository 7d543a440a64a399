"""The package's build (ament_python): what it declares is in setup.cfg; here only the build steps that
generate the SSL wire formats' ``*_pb2.py`` modules from the ``.proto`` files (built, not committed, as
rosidl generates message code)."""

import runpy
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.develop import develop

HERE = Path(__file__).resolve().parent


def write_protos(out_root: Path) -> None:
    """protoc (grpcio-tools) on the .proto files, the modules into the package under ``out_root``."""
    runpy.run_path(str(HERE / "erforce_interfaces/ssl/ssl_proto/generate.py"))["write_modules"](out_root)


class BuildPyWithProtos(build_py):
    """build_py: the modules into the build folder (after the sources are copied: a stale module beside them
    does not win), or beside the sources for an editable install (PEP 660), which imports the package there."""

    def run(self):
        super().run()
        write_protos(HERE if self.editable_mode else Path(self.build_lib))


class DevelopWithProtos(develop):
    """develop (``colcon build --symlink-install``): the modules beside the sources, which it links."""

    def run(self):
        write_protos(HERE)
        super().run()


setup(cmdclass={"build_py": BuildPyWithProtos, "develop": DevelopWithProtos})
