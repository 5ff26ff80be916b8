"""Lazy package exports (PEP 562): a package names its public API, and a name's module is imported on first use.

So ``import rh5_bringup.hardware`` stays cheap and does not pull in what only one of its modules needs.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(package: str, exports: Mapping[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package`` that resolves ``name`` from submodule ``exports[name]``.

    ``exports`` maps each public name to the module (relative to ``package``) that defines it. The value found is
    cached in the package's namespace, so each name is looked up once.
    """

    def __getattr__(name: str) -> Any:  # noqa: N807 (the module hook's required name)
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{exports[name]}", package), name)
        setattr(sys.modules[package], name, value)
        return value

    return __getattr__
