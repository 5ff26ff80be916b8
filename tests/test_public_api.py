"""Every package names its public API, and stays small enough to read (issue 16).

Each package and subpackage of the suite lists its public names in ``__all__`` (unique; ruff keeps it sorted), and
every one of them resolves: the lazy ones (rh5_msgs_py.lazy_exports) import their module on first use, so a name
whose module moved fails here rather than in a user's program; a lazy map names exactly the public names. No
non-test module is over 500 lines.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_planner", "rh5_joint_stabilizer", "rh5_bringup")
MAX_LINES = 500


def _packages() -> list[str]:
    found = []
    for package in PACKAGES:
        top = REPO / package / package
        for init in sorted(top.rglob("__init__.py")):
            found.append(".".join(init.parent.relative_to(top.parent).parts))
    return found


@pytest.mark.parametrize("name", _packages())
def test_every_package_names_its_public_api_and_each_name_resolves(name: str) -> None:
    module = importlib.import_module(name)
    names = getattr(module, "__all__", None)
    assert names is not None, f"{name} has no __all__"
    assert list(names) == sorted(set(names), key=list(names).index), f"{name}.__all__ repeats a name"
    missing = [n for n in names if not hasattr(module, n) and importlib.util.find_spec(f"{name}.{n}") is None]
    assert missing == [], f"{name}.__all__ names what it does not have: {missing}"
    lazy = getattr(module, "_EXPORTS", None)
    if lazy is not None:  # the lazy map and the public names are one list
        assert set(lazy) == set(names), f"{name}: _EXPORTS and __all__ differ by {set(lazy) ^ set(names)}"


def _modules() -> list[Path]:
    found = []
    for package in PACKAGES:
        found += list((REPO / package / package).rglob("*.py"))
    found += sorted((REPO / "bench").glob("*.py")) + sorted((REPO / "tools").glob("*.py"))
    return sorted(found)


def test_no_module_is_over_500_lines() -> None:
    lines = {str(p.relative_to(REPO)): len(p.read_text(encoding="utf-8").splitlines()) for p in _modules()}
    assert {name: n for name, n in lines.items() if n > MAX_LINES} == {}
