"""The package's build (ament_python): everything it declares is in setup.cfg."""

from setuptools import setup

setup()
