"""./run setup registers the four packages in the ament index of .venv as colcon build --symlink-install
would: what each setup.cfg declares (data_files, console_scripts) is there, the data files as symlinks to the
sources, and ROS 2's own index library and CLI (ament_index_python) find the packages."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix, get_package_share_directory, get_packages_with_prefixes
from setuptools.config.setupcfg import read_configuration

from erforce_interfaces.wire import ament_index

REPO = Path(__file__).resolve().parents[2]
PACKAGES = ("erforce_interfaces", "erforce_ball_model", "erforce_motion", "erforce_sim")
PREFIX = Path(sys.prefix)  # the venv ./run setup prepared


def expected_index(package_dir: Path) -> tuple[dict[Path, Path], set[str]]:
    """{path in the prefix: source file} of the data files, and the console script names, as the package's
    setup.cfg declares them (read by setuptools' own parser)."""
    options = read_configuration(package_dir / "setup.cfg")["options"]
    files = {Path(dest) / Path(name).name: package_dir / name
             for dest, names in options["data_files"] for name in names}
    scripts = {spec.split("=")[0].strip() for spec in options["entry_points"]["console_scripts"]}
    return files, scripts


@pytest.mark.parametrize("pkg", PACKAGES)
def test_the_index_in_the_venv_holds_what_setup_py_installs(pkg):
    files, scripts = expected_index(REPO / "src" / pkg)
    assert Path("share/ament_index/resource_index/packages") / pkg in files
    assert any(p.parts[:3] == ("share", pkg, "launch") for p in files) or pkg == "erforce_ball_model"
    for installed, source in files.items():
        path = PREFIX / installed
        assert path.is_symlink() and path.samefile(source), installed  # a source edit shows at once
    share = PREFIX / "share" / pkg
    assert {p.relative_to(PREFIX) for p in share.rglob("*") if not p.is_dir()} == {
        p for p in files if p.parts[:2] == ("share", pkg)}  # nothing stale
    lib = PREFIX / "lib" / pkg
    assert {p.name for p in lib.iterdir()} == scripts
    for exe in lib.iterdir():
        assert os.access(exe, os.X_OK) and exe.read_text().startswith(f"#!{sys.executable}\n")


def test_ros2s_own_index_library_and_cli_find_the_packages(monkeypatch):
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(PREFIX))
    found = get_packages_with_prefixes()
    for pkg in PACKAGES:
        assert found[pkg] == str(PREFIX) and get_package_prefix(pkg) == str(PREFIX)
        assert Path(get_package_share_directory(pkg)) == PREFIX / "share" / pkg
        assert ament_index.find_package_share(pkg) == PREFIX / "share" / pkg  # ours prefers the index
    listing = subprocess.run([str(PREFIX / "bin" / "ament_index"), "packages"], capture_output=True, text=True,
                             check=True, env={**os.environ, "AMENT_PREFIX_PATH": str(PREFIX)}).stdout
    assert {line.split()[0] for line in listing.splitlines() if line.startswith("erforce_")} == set(PACKAGES)


def test_without_the_index_a_package_is_found_in_its_sources(monkeypatch, tmp_path):
    monkeypatch.setenv("AMENT_PREFIX_PATH", "")
    monkeypatch.setattr(sys, "prefix", str(tmp_path))  # an interpreter whose prefix holds no index
    assert ament_index.find_package_share("erforce_sim") == REPO / "src" / "erforce_sim"


def test_the_venvs_own_index_is_found_when_the_environment_names_none(monkeypatch, tmp_path):
    # as .venv/bin/python or .venv/bin/erforce-launch run without ./run exec
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    assert ament_index.ament_prefixes() == [PREFIX]
    assert ament_index.find_package_prefix("erforce_interfaces") == PREFIX
    assert ament_index.find_package_share("erforce_sim") == PREFIX / "share" / "erforce_sim"
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path))  # a prefix the user names comes first
    assert ament_index.ament_prefixes() == [tmp_path, PREFIX]


def test_a_launch_run_from_the_venv_without_its_environment_resolves_the_packages_prefix():
    # bench_lockstep --launch-runs as `.venv/bin/python bench/bench_lockstep.py`: the launch files' predictor
    # prefix $(find-pkg-prefix erforce_interfaces)/lib/erforce_interfaces/erforce-realtime must exist
    env = {"HOME": os.environ.get("HOME", "/tmp"), "PATH": "/usr/bin:/bin"}
    printed = subprocess.run([str(PREFIX / "bin" / "erforce-launch"), "--print",
                              str(REPO / "src/erforce_sim/launch/team_sim.launch.yaml")],
                             capture_output=True, text=True, timeout=120, env=env, check=True).stdout
    prefixes = set(re.findall(r"(\S*/erforce-realtime)\b", printed))
    assert prefixes == {str(PREFIX / "lib" / "erforce_interfaces" / "erforce-realtime")}, printed[-2000:]
    assert os.access(next(iter(prefixes)), os.X_OK)


def test_a_registered_executable_runs_as_ros2_run_would_start_it():
    result = subprocess.run([str(PREFIX / "lib" / "erforce_interfaces" / "erforce-launch"), "--help"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and "usage: erforce-launch" in result.stdout


def test_registering_again_replaces_what_is_stale(tmp_path, monkeypatch):
    stale_launch = tmp_path / "share/erforce_motion/launch/gone.launch.yaml"
    stale_exe = tmp_path / "lib/erforce_motion/gone"
    for path in (stale_launch, stale_exe):
        path.parent.mkdir(parents=True)
        path.write_text("stale")
    ament_index.register_package(tmp_path, REPO / "src" / "erforce_motion")
    files, scripts = expected_index(REPO / "src" / "erforce_motion")
    assert not stale_launch.exists() and not stale_exe.exists()
    assert {p.relative_to(tmp_path) for p in tmp_path.rglob("*") if not p.is_dir()} == set(files) | {
        Path("lib/erforce_motion") / name for name in scripts}
