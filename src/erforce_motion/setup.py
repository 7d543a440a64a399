from glob import glob

from setuptools import find_packages, setup

package_name = "erforce_motion"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["params/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", glob("launch/*.yaml")),
        # the nodes' parameter schemas (param_schema.py): read from the Python package, also in share/ for tools
        ("share/" + package_name + "/params", glob(package_name + "/params/*.yaml")),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="ER-Force stack maintainers",
    maintainer_email="info@robotics-erlangen.de",
    description="Omni-wheel velocity control and motor-board cascade (ETDP 2016 Sec. 4)",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "velocity_controller = erforce_motion.velocity_controller_node:main",
            "motor_boards = erforce_motion.motor_boards_node:main",
            "team_firmware = erforce_motion.team_firmware_node:main",
        ],
    },
)
