"""Generated documentation stays in step with its sources."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def test_parameter_docs_match_the_specs() -> None:
    result = subprocess.run(
        [sys.executable, str(REPO_ROOT / "tools" / "write_parameter_docs.py"), "--check"], check=False, timeout=60
    )
    assert result.returncode == 0, "docs/parameters.md is stale: run .venv/bin/python tools/write_parameter_docs.py"
