"""ament_python package; node executables install into lib/<package>/ (setup.cfg) for ros2 run."""

import xml.etree.ElementTree as ET
from pathlib import Path

from setuptools import Extension, find_packages, setup

PACKAGE = "rh5_bringup"
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
        *share_files("viz"),
    ],
    # The NDLCom deframing loop in C (rh5_bringup/hardware/ndlcom/_framing.c): the 1 kHz cycle's per-byte work.
    ext_modules=[
        Extension(
            f"{PACKAGE}.hardware.ndlcom._framing", [f"{PACKAGE}/hardware/ndlcom/_framing.c"], extra_compile_args=["-O2"]
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
            "control_node = rh5_bringup.control.node:main",
            "driver_node = rh5_bringup.hardware.driver_node:main",
            "sim_hardware_node = rh5_bringup.sim.hardware_node:main",
            "recorder_node = rh5_bringup.recording.recorder_node:main",
            "rh5 = rh5_bringup.orchestration.cli:main",
        ],
    },
)
