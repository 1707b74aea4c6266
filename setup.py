from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(
    packages=["sparse_nav", "sparse_nav.sim", "sparse_nav.ros", "sparse_nav.exit_finder",
              "sparse_nav.tools", "sparse_nav.conductor", "sparse_nav.navigation",
              "sparse_nav.cartographer", "sparse_nav.motion"],
    package_dir={"": "src"},
    package_data={"sparse_nav.exit_finder": ["door_ranker.json"]},
))
