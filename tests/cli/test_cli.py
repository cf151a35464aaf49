"""The ``negobs`` console script: every command has --help, bad options fail cleanly."""

from __future__ import annotations

import subprocess
import sys

import pytest

from negobs_gym.cli import COMMAND_MODULES, build_parser, main


@pytest.mark.parametrize("command", COMMAND_MODULES)
def test_every_command_has_help(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert f"negobs {command}" in capsys.readouterr().out


def test_top_level_help_lists_every_command(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert all(command in out for command in COMMAND_MODULES)


def test_a_command_is_required_and_bad_values_are_named(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([])
    assert exit_info.value.code == 2
    with pytest.raises(SystemExit):
        build_parser().parse_args(["demo", "--seed", "-3"])
    assert "--seed" in capsys.readouterr().err


# slow (end to end): the demo's episodes and PNG are checked by tests/test_demo.py; this adds the
# CLI's detection campaign
@pytest.mark.slow
def test_demo_command_writes_the_png_and_the_detection_tables(tmp_path, monkeypatch):
    import negobs_gym.demo as demo

    driven = {}
    drive = demo.run_episode

    def driven_once(seed: int, filtered: bool):
        driven[seed, filtered] = drive(seed, filtered)
        return driven[seed, filtered]

    monkeypatch.setattr(demo, "run_episode", driven_once)
    out = tmp_path / "demo.png"
    evaluation = tmp_path / "eval"
    args = ["-q", "demo", "--out", str(out), "--seed", "2", "--eval-out", str(evaluation), "--frames", "4"]
    assert main(args) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Table 6" in (evaluation / "tables.md").read_text()
    for png in ("fig16.png", "recall_heatmap.png"):
        assert (evaluation / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(driven) == {(2, False), (2, True)}
    # --no-detection: the same two episodes (driven above, replayed here) and no campaign
    monkeypatch.setattr(demo, "run_episode", lambda seed, filtered: driven[seed, filtered])
    alone = tmp_path / "alone.png"
    args = [
        "-q",
        "demo",
        "--out",
        str(alone),
        "--seed",
        "2",
        "--no-detection",
        "--eval-out",
        str(tmp_path / "none"),
    ]
    assert main(args) == 0
    assert alone.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (tmp_path / "none").exists()


def test_a_path_that_cannot_be_written_is_one_line_and_a_traceback_with_verbose(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    args = ["scenario", "render", "paper_t_straight", "--out", str(blocker / "frame.png")]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[Errno" in err[0] and str(blocker) in err[0]  # no traceback
    with pytest.raises(OSError):
        main(["-v", *args])


def test_a_package_error_is_one_line_and_exit_code_2(capsys):
    assert main(["scenario", "show", "no_such_scene"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == ""
    assert len(err) == 1  # no traceback
    assert err[0].startswith("negobs scenario: scenario: unknown scenario 'no_such_scene'")


# a bug (not a NegobsError) stands in for the spec writer, run as the console script runs it
_BUG = """
import negobs_gym.spec
def broken(spec):
    raise ZeroDivisionError("a bug, not bad input")
negobs_gym.spec.spec_to_toml = broken
from negobs_gym.cli import main
raise SystemExit(main(["scenario", "show", "braking_v1"]))
"""


def test_an_unexpected_exception_keeps_its_traceback():
    done = subprocess.run([sys.executable, "-c", _BUG], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1  # Python's own exit code for an uncaught exception, not the CLI's 2
    assert "Traceback (most recent call last)" in done.stderr
    assert "ZeroDivisionError: a bug, not bad input" in done.stderr
