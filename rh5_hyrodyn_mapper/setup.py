"""ament_python package; node executables install into lib/<package>/ (setup.cfg) for ros2 run."""

import xml.etree.ElementTree as ET
from pathlib import Path

from setuptools import Extension, find_packages, setup

PACKAGE = "rh5_hyrodyn_mapper"
HERE = Path(__file__).parent


def share_files(folder: str) -> list[tuple[str, list[str]]]:
    """Install every file of ``folder`` (if present) into share/<package>/<folder>."""
    files = sorted(str(p.relative_to(HERE)) for p in (HERE / folder).glob("*") if p.is_file())
    return [(f"share/{PACKAGE}/{folder}", files)] if files else []


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={"": ["*.yaml", "params/*.yaml", "config/*.yaml", "*.json", "py.typed"]},
    include_package_data=True,
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        *share_files("launch"),
        *share_files("config"),
    ],
    # Every submechanism's joint <-> actuator maths in C (kinematics/unit_maps.c, called through _compiled.c): one
    # kernel for one sample (the 1 kHz control cycle) and for whole trajectories; required, no other implementation.
    ext_modules=[
        Extension(
            f"{PACKAGE}.kinematics._compiled",
            [f"{PACKAGE}/kinematics/_compiled.c", f"{PACKAGE}/kinematics/unit_maps.c"],
            depends=[f"{PACKAGE}/kinematics/unit_maps.h"],
            extra_compile_args=["-O3"],
        )
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="RH5 control suite developers",
    maintainer_email="rh5-control@users.noreply.github.com",
    description=ET.parse(HERE / "package.xml").findtext("description"),
    license="BSD-3-Clause",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "mapper_node = rh5_hyrodyn_mapper.mapper_node:main",
            "state_publisher_node = rh5_hyrodyn_mapper.state_publisher_node:main",
            "rh5_urdf = rh5_hyrodyn_mapper.model.urdf:main",
        ],
    },
)
