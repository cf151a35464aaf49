"""The scripts in ``examples/`` run as their docstrings say (with short settings), so they cannot rot."""

from __future__ import annotations

import runpy
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PNG = b"\x89PNG\r\n\x1a\n"


def _run(monkeypatch: pytest.MonkeyPatch, script: str, *argv: str) -> dict:
    """Run ``examples/script`` as ``python examples/script argv...`` would, in this process."""
    path = EXAMPLES / script
    monkeypatch.setattr(sys, "argv", [str(path), *argv])
    return runpy.run_path(str(path), run_name="__main__")


def test_coverage_figure(tmp_path: Path, monkeypatch, capsys) -> None:
    out = tmp_path / "coverage.png"
    _run(monkeypatch, "coverage_fig3_4.py", "--out", str(out))
    assert out.read_bytes()[:8] == PNG
    printed = capsys.readouterr().out
    assert "HDL-64 ring gap (Eq. 3): 8 m: 0.28 m" in printed  # paper N Eq. 3 at 2.2 m
    assert "side HDL-32 radial spacing at 10 m" in printed


def test_scripted_braking_stops_before_the_ditch(monkeypatch, capsys) -> None:
    _run(monkeypatch, "scripted_braking.py", "--episodes", "1")
    assert capsys.readouterr().out.splitlines()[-1] == "stopped_before=1/1"


def test_train_ppo_saves_a_model_and_its_evaluations(tmp_path: Path, monkeypatch) -> None:
    out = tmp_path / "ppo"
    args = ["--env", "negobs_gym/Braking-v1", "--source", "oracle", "--steps", "64", "--n-steps", "64"]
    with pytest.raises(SystemExit) as exit_info:
        _run(monkeypatch, "train_ppo.py", *args, "--eval-episodes", "1", "--no-progress", "--out", str(out))
    assert exit_info.value.code == 0
    assert (out / "model.zip").is_file() and len((out / "eval.csv").read_text().splitlines()) == 2


def _pytest_the_example(*options: str) -> str:
    """``python -m pytest examples/test_my_scenario.py`` as its docstring says, with ``options``;
    asserts it passes and returns what it printed."""
    command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *options]
    done = subprocess.run(
        [*command, str(EXAMPLES / "test_my_scenario.py")],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=EXAMPLES.parent,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def test_my_scenario_example_passes_on_its_first_seed() -> None:
    """pytest collects the example (so its imports still work) and its scripted-driver test passes
    on the first of its three seeds. The policy half, a 15 s detector episode, runs in the slow
    test below; the shipped ppo_offroad_nav_v1 driving a scenario run stays in the default suite in
    tests/cli/test_scenario_cli.py::test_run_policy_drives_and_is_recorded_in_the_spec."""
    assert "1 passed, 3 deselected" in _pytest_the_example("-k", "filter_stops and 0]")


@pytest.mark.slow
def test_my_scenario_example_passes_on_its_first_seed_with_its_policy() -> None:
    """The scripted test's first seed and the policy's one seed, as the default run did before."""
    assert "2 passed, 2 deselected" in _pytest_the_example("-k", "0]")
