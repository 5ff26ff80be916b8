"""Run benchmarks on an older revision and on this tree in one run, alternately, and print new/old ratios.

Not a test. For a refactoring that must not make anything slower (issue 16): the older revision is checked out into a
temporary git worktree with its C extensions built, and gets a prefix of its own (a virtual environment that reuses
this one's packages but runs the old code and the old console scripts, since node processes start from
``sys.prefix/bin``). Each benchmark then runs ``--rounds`` times on each side, old first, alternating, so both
see the same hour of a shared machine. Every output line that starts with a label and then a number is a measure;
the table shows each measure's median on both sides and new/old (for times below 1 is faster, for rates above).

    .venv/bin/python bench/compare_revisions.py BASE_REV [--rounds 2] -- bench/mapper.py bench/codec.py --seconds 0.5
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path
from statistics import median

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_planner", "rh5_joint_stabilizer", "rh5_bringup")
MEASURE = re.compile(r"^\s*(?P<label>\S.*?)\s{2,}(?P<value>[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?)(?![\w.])")
"""A benchmark's table row: a label, two or more spaces, a number (the first column after the label)."""


def measures(text: str) -> dict[str, float]:
    """Label -> value of every table row in ``text`` (the first row of a label wins)."""
    found: dict[str, float] = {}
    for line in text.splitlines():
        match = MEASURE.match(line)
        if match and match["label"] not in found:
            found[match["label"]] = float(match["value"])
    return found


def _console_scripts(setup_py: Path) -> list[tuple[str, str]]:
    """(name, "module:function") of every console script a package's setup.py declares."""
    return re.findall(r'"([\w-]+)\s*=\s*([\w.]+:\w+)"', setup_py.read_text(encoding="utf-8"))


def prepare_base(rev: str, where: Path) -> Path:
    """Check ``rev`` out at ``where/src``, build its C extensions and make a prefix that runs it; return its python."""
    src = where / "src"
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(src), rev], check=True)
    for package in PACKAGES:
        if "ext_modules" in (src / package / "setup.py").read_text(encoding="utf-8"):
            subprocess.run(
                [sys.executable, "setup.py", "-q", "build_ext", "--inplace"],
                cwd=src / package,
                check=True,
                capture_output=True,
            )
    prefix = where / "prefix"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(prefix)], check=True)
    site = Path(sysconfig.get_paths(vars={"base": str(prefix), "platbase": str(prefix)})["purelib"])
    ours = sysconfig.get_paths()["purelib"]
    paths = "\n".join(str(src / p) for p in PACKAGES)
    (site / "00_base_revision.pth").write_text(f"{paths}\nimport site; site.addsitedir({ours!r})\n", encoding="utf-8")
    python = prefix / "bin" / "python"
    for package in PACKAGES:
        for name, target in _console_scripts(src / package / "setup.py"):
            module, function = target.split(":")
            script = prefix / "bin" / name
            script.write_text(f"#!{python}\nimport sys\nfrom {module} import {function}\nsys.exit({function}())\n")
            script.chmod(0o755)
    return python


def run(python: Path, cwd: Path, bench: list[str]) -> str:
    """One run of a benchmark command line (script and arguments) with ``python`` in ``cwd``; its stdout."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    result = subprocess.run([str(python), *bench], cwd=cwd, env=env, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        print(f"  {' '.join(bench)} failed in {cwd}:\n{result.stderr[-1500:]}", file=sys.stderr)
    return result.stdout


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", help="the older revision (commit, tag, branch)")
    parser.add_argument("--rounds", type=int, default=2, help="runs per side and benchmark, alternating")
    parser.add_argument("bench", nargs="+", help="after --: benchmark scripts, each with its own arguments after it")
    args = parser.parse_args(argv)
    commands: list[list[str]] = []
    for item in args.bench:
        if item.endswith(".py"):
            commands.append([item])
        elif commands:
            commands[-1].append(item)
    with tempfile.TemporaryDirectory(prefix="rh5_compare_") as tmp:
        base_python = prepare_base(args.base, Path(tmp))
        try:
            for command in commands:
                old: list[dict[str, float]] = []
                new: list[dict[str, float]] = []
                for round_ in range(args.rounds):
                    print(f"{' '.join(command)}: round {round_ + 1} of {args.rounds} ...", file=sys.stderr, flush=True)
                    old.append(measures(run(base_python, Path(tmp) / "src", command)))
                    new.append(measures(run(Path(sys.executable), REPO, command)))
                labels = [label for label in new[0] if all(label in m for m in (*old, *new))]
                print(f"\n{' '.join(command)}: {args.base} (old) against this tree (new), median of {args.rounds}")
                print(f"  {'measure':<60} {'old':>11} {'new':>11}  new/old")
                for label in labels:
                    a, b = median(m[label] for m in old), median(m[label] for m in new)
                    ratio = f"{b / a:7.2f}" if a else "      -"
                    print(f"  {label[:60]:<60} {a:11.4g} {b:11.4g}  {ratio}")
        finally:
            subprocess.run(
                ["git", "-C", str(REPO), "worktree", "remove", "--force", str(Path(tmp) / "src")], check=False
            )
            shutil.rmtree(Path(tmp) / "src", ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
