"""``rh5-plan``: planning writes the trajectory file, plots and limit table with a progress bar; --list, --table,
--design; bad input exits 2. Real solves of a 20-knot squat (a few seconds each), in-process; the installed console
script is run for the cheap paths (no solve)."""

from __future__ import annotations

import io
import shutil
import subprocess
from pathlib import Path

import pytest

from rh5_hyrodyn_mapper.model import model_hash
from rh5_msgs_py.trajectory_file import load_trajectory
from rh5_planner.motions import MOTIONS
from rh5_planner.plan_cli import ProgressBar, main, parse_overrides

SHORT = ["--set", "total_time_s=0.6", "--set", "hold_s=0.1", "--set", "com_range_m=0.1"]
SCRIPT = shutil.which("rh5-plan") or str(Path(__file__).resolve().parents[2] / ".venv" / "bin" / "rh5-plan")


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    code = main(list(argv), out=out, err=err)
    return code, out.getvalue(), err.getvalue()


def test_plan_writes_file_plots_table_and_shows_progress(tmp_path: Path) -> None:
    code, out, err = run("squat_with_5kg_weights", *SHORT, "--output-dir", str(tmp_path), "--max-iterations", "60")
    assert code == 0, err
    name = "squat_with_5kg_weights"
    data = load_trajectory(tmp_path / f"{name}.rh5traj", expected_model_hash=model_hash())
    assert data.motion["parameters"]["total_time_s"] == 0.6
    assert data.solver_log["converged"]
    for png in (f"{name}_cop.png", f"{name}_joints.png", f"{name}_actuators.png"):
        assert (tmp_path / png).read_bytes()[:4] == b"\x89PNG"
    table = (tmp_path / f"{name}_limits.md").read_text(encoding="utf-8")
    assert "| Motion | Conv. | Pos. Lim." in table
    assert "| LLKnee |" in table
    # progress bar on stderr: iteration, cost, elapsed, and the verdict
    bar_lines = [line for line in err.splitlines() if "] it " in line]
    assert bar_lines
    assert " cost " in bar_lines[-1]
    assert bar_lines[-1].rstrip().endswith("converged")
    assert " s" in bar_lines[-1]
    # summary on stdout
    assert "converged after" in out
    assert f"{name}.rh5traj" in out
    assert "Pos. Lim." in out


def test_no_plots(tmp_path: Path) -> None:
    code, _, err = run("squat_with_5kg_weights", *SHORT, "--output-dir", str(tmp_path), "--no-plots")
    assert code == 0, err
    assert not list(tmp_path.glob("*.png"))
    assert (tmp_path / "squat_with_5kg_weights.rh5traj").exists()


def test_table_compares_with_the_paper(tmp_path: Path) -> None:
    code, out, err = run("--table", "squat_with_5kg_weights", *SHORT, "--output-dir", str(tmp_path))
    assert code == 0, err
    # planned with the actuator limits (the default since issue 14): the row says so
    assert "| squat_with_5kg_weights +act | yes | \u2713 | \u2713 | \u2713 |" in out
    assert "squat_with_5kg_weights / Vel. Lim.: paper \u2713, ours \u2713: agree" in out
    assert "3/3 cells agree" in out
    assert (tmp_path / "feasibility.md").read_text(encoding="utf-8") in out


def test_design_stops_at_the_first_feasible_scaling() -> None:
    code, out, err = run(
        "--design", "squat_with_5kg_weights", *SHORT, "--scale", "knee:velocity", "--factors", "1,3", "--no-plots"
    )
    assert code == 0, err
    assert "step 1: knee velocity x1" in out
    assert "step 2" not in out
    assert "feasible with the nominal limits" in out
    assert "feasible" in err  # the progress bar ends each re-plan with its verdict


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["moonwalk"], "unknown motion 'moonwalk'"),
        (["squat_with_5kg_weights", "--set", "lenght_m=0.4"], "unknown parameters ['lenght_m']"),
        (["squat_with_5kg_weights", "--set", "com_range_m=deep"], "com_range_m must be float"),
        (["squat_with_5kg_weights", "--set", "com_range_m"], "expected key=value"),
        (["squat_with_5kg_weights", "--set", "dt=-0.1"], "dt must be a positive"),
        (["squat_with_5kg_weights", "--max-iterations", "0"], "--max-iterations must be >= 1"),
        (["--table", "squat_with_5kg_weights", "moonwalk"], "unknown motion 'moonwalk'"),
        (["--design", "squat_with_5kg_weights", "--scale", "tail:velocity"], "matches no joint"),
        (["--design", "squat_with_5kg_weights", "--scale", "knee:speed"], "unknown limit kind"),
        (["--design", "squat_with_5kg_weights", "--factors", "1,x"], "comma-separated numbers"),
        (["squat_with_5kg_weights", "--scale", "knee:velocity"], "--scale only applies with --design"),
        ([], "a MOTION"),
        (["squat_with_5kg_weights", "--output-dir", __file__], "not a folder"),
    ],
)
def test_bad_input_exits_2(argv: list[str], message: str) -> None:
    code, out, err = run(*argv)
    assert code == 2
    assert message in err
    assert "usage: rh5-plan" in err
    assert "] it " not in err  # nothing was solved
    assert out == ""


def test_parse_overrides_reads_yaml_values() -> None:
    assert parse_overrides(["length_m=0.4", "n_steps=6", "costs=[foot, com]", "track_com=true"]) == {
        "length_m": 0.4,
        "n_steps": 6,
        "costs": ["foot", "com"],
        "track_com": True,
    }


def test_progress_bar_on_a_terminal_redraws_one_line() -> None:
    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    stream = Tty()
    bar = ProgressBar(100, 1e-7, stream=stream, width=10)
    for i, stop in enumerate((1e1, 1e-2, 1e-5, 1e-8)):
        bar(i, 100.0 - i, stop)
    bar.finish("converged")
    text = stream.getvalue()
    assert text.count("\r") == 5
    assert text.count("\n") == 1
    assert "[##########] it 3/100" in text  # stop 1e-8 < threshold: full
    assert "[####......] it 1/100" in text  # stop 1e1 -> 1e-2: 3 of the 8 decades to the threshold
    assert ProgressBar(10, 1e-7).fraction(5, float("nan")) == 0.5


def test_console_script_lists_motions_and_rejects_unknown_ones() -> None:
    listing = subprocess.run([SCRIPT, "--list"], capture_output=True, text=True, timeout=60, check=False)
    assert listing.returncode == 0, listing.stderr
    for name in MOTIONS:
        assert f"{name}: " in listing.stdout
    assert "    length_m = 0.5" in listing.stdout
    bad = subprocess.run([SCRIPT, "moonwalk"], capture_output=True, text=True, timeout=60, check=False)
    assert bad.returncode == 2
    assert "unknown motion" in bad.stderr
    flag = subprocess.run([SCRIPT, "--no-such-flag"], capture_output=True, text=True, timeout=60, check=False)
    assert flag.returncode == 2
