from glob import glob

from setuptools import find_packages, setup

package_name = "erforce_interfaces"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["params/*.yaml"], "erforce_interfaces.ssl.ssl_proto": ["*.proto"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", glob("launch/*.yaml")),
        # the nodes' parameter schemas (param_schema.py): read from the Python package, also in share/ for tools
        ("share/" + package_name + "/params", glob(package_name + "/params/*.yaml")),
        ("share/" + package_name + "/config", glob("config/*.yaml") + glob("config/*.xml")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="ER-Force stack maintainers",
    maintainer_email="info@robotics-erlangen.de",
    description="Wire contract, node runtime, SSL wire formats and developer tools",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "erforce-launch = erforce_interfaces.tools.launcher:main",
            "erforce-topic = erforce_interfaces.tools.topic_tool:main",
            "erforce-record = erforce_interfaces.tools.recording:main",
            "erforce-realtime = erforce_interfaces.tools.realtime:main",
            "ssl_log_replay = erforce_interfaces.ssl.ssl_log_replay:main",
            "talker = erforce_interfaces.runtime.demo_nodes:talker_main",
            "listener = erforce_interfaces.runtime.demo_nodes:listener_main",
        ],
    },
)
