from glob import glob

from setuptools import find_packages, setup

package_name = "erforce_ball_model"

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
    description="Two-phase ball model, tracking and catch-time prediction (ETDP 2016 Sec. 5)",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "ball_predictor = erforce_ball_model.ball_predictor_node:main",
            "ball_figures = erforce_ball_model.figures:main",
            "ball_fit = erforce_ball_model.ball_fit:main",
            "catcher = erforce_ball_model.catcher_node:main",
            "passing_game = erforce_ball_model.passing.passing_game_node:main",
            "ssl_ball_predictor = erforce_ball_model.ssl_ball_predictor:main",
            "ssl_vision_bridge = erforce_ball_model.ssl_vision_bridge_node:main",
            "team_catcher = erforce_ball_model.team_catcher_node:main",
        ],
    },
)
