from glob import glob

from setuptools import find_packages, setup

package_name = "erforce_sim"

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
        ("share/" + package_name + "/config", glob("config/*.yaml") + glob("config/*.json")),
        ("share/" + package_name + "/web", glob("web/*")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="ER-Force stack maintainers",
    maintainer_email="info@robotics-erlangen.de",
    description="Physics plant simulator for the ER-Force stack (ETDP 2016 Sec. 2-3)",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "plant = erforce_sim.plant_node:main",
            "tune_motor = erforce_sim.in_process.tuning_experiment:main",
            "ssl_sim_server = erforce_sim.ssl_sim_server_node:main",
            "ssl_sim_bridge = erforce_sim.ssl_sim_bridge_node:main",
            "ssl_game_log = erforce_sim.demo.ssl_game_log:main",
            "field_view = erforce_sim.view.field_view_node:main",
        ],
    },
)
