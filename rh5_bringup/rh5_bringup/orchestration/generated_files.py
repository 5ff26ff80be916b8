"""The files rendered from the bringup description (launch file, params files): write them, or check the committed
ones, with one command-line shape for each kind."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping
from pathlib import Path

__all__ = ["Renderer", "generated_files_main"]

Renderer = Callable[[Path], Mapping[Path, str]]
"""Target folder -> the files to write there (path -> text)."""


def generated_files_main(
    module: str, description: str, default_dir: Path, render: Renderer, argv: list[str] | None
) -> int:
    """``python -m <module> [--check] [--dir DIR]``: write what ``render(dir)`` returns (path -> text), or with
    ``--check`` exit 1 and name every committed file that differs from it."""
    parser = argparse.ArgumentParser(prog=f"python -m {module}", description=description)
    parser.add_argument("--check", action="store_true", help="exit 1 if a committed file is stale")
    parser.add_argument("--dir", type=Path, default=default_dir, help=f"target folder (default: {default_dir})")
    args = parser.parse_args(argv)
    files = render(args.dir)
    if args.check:
        stale = [str(p) for p, text in files.items() if not p.exists() or p.read_text(encoding="utf-8") != text]
        if stale:
            print(f"{', '.join(stale)} is stale: run python -m {module}", file=sys.stderr)
            return 1
        return 0
    args.dir.mkdir(parents=True, exist_ok=True)
    for path, text in files.items():
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path}")
    return 0
