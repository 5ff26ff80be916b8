"""Build the interface packages the PyPI wheels lack (interfaces/: tf2_msgs, control_msgs) into a venv.

Run by ``make venv`` with the venv's interpreter, after pip has installed the pinned set (which includes the
rosidl generators and ament_cmake). The recipe is the measured one of ../shared/design/ros2_wheels.md 6c, with
its two traps handled:

1. the wheels' dependency metadata is incomplete: requirements.txt lists the ament/rosidl CMake packages the
   generators need but do not declare;
2. the message wheels' CMake export files name the include paths of the machine that built them
   (``/opt/python/cp311-cp311/...``): they are rewritten to this venv's Python and numpy headers, every time,
   since a reinstalled wheel brings them back.

Each package is configured, built and installed with CMake into the venv itself, so the Python package lands in
site-packages, its libraries in ``.venv/lib`` (on the ROS wheels' library path) and its ``.msg`` files and ament
index entry in ``.venv/share``. A package that already imports and was not built here (a full ROS install) is
left alone; one built here from other sources is rebuilt.

    .venv/bin/python tools/build_interfaces.py [--force]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SOURCES = REPO / "interfaces"
PACKAGES = {"tf2_msgs": "tf2_msgs.msg", "control_msgs": "control_msgs.action"}
"""Package -> the module whose import shows it is usable."""
MARKER = "rh5_interfaces.sha256"
"""Written into share/<package>/ of the venv: the hash of the sources it was built from."""
BUILD_MACHINE_PATHS = re.compile(
    r"/opt/python/cp3\d+-cp3\d+/(include/python3\.\d+|lib/python3\.\d+/site-packages/numpy/_core/include)"
)


def sources_hash(package: str) -> str:
    """SHA-256 over every file of the package's source folder (names and contents)."""
    digest = hashlib.sha256()
    for path in sorted((SOURCES / package).rglob("*")):
        if path.is_file():
            digest.update(str(path.relative_to(SOURCES)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def importable(module: str) -> bool:
    """Whether ``module`` imports in a fresh interpreter of this venv (its libraries load too)."""
    probe = f"import {module}, importlib; importlib.import_module('{module}')"
    return subprocess.run([sys.executable, "-c", probe], capture_output=True, check=False).returncode == 0


def fix_build_machine_paths(prefix: Path) -> int:
    """Point the wheels' CMake export files at this venv's Python and numpy headers; return how many changed."""
    import numpy  # noqa: PLC0415 (the venv's numpy, only needed here)

    python_include = sysconfig.get_paths()["include"]
    numpy_include = numpy.get_include()

    def replace(match: re.Match[str]) -> str:
        return python_include if match.group(1).startswith("include") else numpy_include

    changed = 0
    for path in (prefix / "share").glob("*/cmake/*.cmake"):
        text = path.read_text(encoding="utf-8", errors="surrogateescape")
        if "/opt/python/" not in text:
            continue
        new = BUILD_MACHINE_PATHS.sub(replace, text)
        if new != text:
            path.write_text(new, encoding="utf-8", errors="surrogateescape")
            changed += 1
    return changed


def build(package: str, prefix: Path, jobs: int) -> None:
    """Configure, build and install one interface package into ``prefix``."""
    build_dir = prefix / ".interfaces-build" / package
    env = {
        **os.environ,
        "AMENT_PREFIX_PATH": str(prefix),
        "CMAKE_PREFIX_PATH": str(prefix),
    }
    configure = [
        "cmake",
        "-S",
        str(SOURCES / package),
        "-B",
        str(build_dir),
        f"-DCMAKE_INSTALL_PREFIX={prefix}",
        f"-DCMAKE_PREFIX_PATH={prefix}",
        f"-DPython3_EXECUTABLE={sys.executable}",
        "-DBUILD_TESTING=OFF",
    ]
    build_and_install = (["cmake", "--build", str(build_dir), "-j", str(jobs)], ["cmake", "--install", str(build_dir)])
    for command in (configure, *build_and_install):
        result = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
        if result.returncode != 0:
            sys.stderr.write(result.stdout[-4000:] + result.stderr[-4000:])
            msg = f"{package}: `{' '.join(command[:2])}` failed (exit {result.returncode}); output above"
            raise SystemExit(msg)
    (prefix / "share" / package / MARKER).write_text(sources_hash(package) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    """Build what is missing or stale; exit 1 when a package still does not import afterwards."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--force", action="store_true", help="rebuild even when the packages are up to date")
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel compile jobs")
    args = parser.parse_args(argv)
    prefix = Path(sys.prefix)
    for package, module in PACKAGES.items():
        marker = prefix / "share" / package / MARKER
        if not args.force and importable(module):
            if not marker.exists():
                print(f"build_interfaces: {package}: using the installed package (not built here)")
                continue
            if marker.read_text(encoding="utf-8").strip() == sources_hash(package):
                print(f"build_interfaces: {package}: up to date")
                continue
        started = time.monotonic()
        fixed = fix_build_machine_paths(prefix)
        if fixed:
            print(f"build_interfaces: pointed {fixed} CMake export files at this venv's Python and numpy headers")
        build(package, prefix, args.jobs)
        if not importable(module):
            print(f"build_interfaces: {package} was built but `import {module}` fails", file=sys.stderr)
            return 1
        print(f"build_interfaces: {package}: built and installed into {prefix} in {time.monotonic() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
