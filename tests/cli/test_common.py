"""Argument types and option checks shared by the commands and the benchmarks."""

from __future__ import annotations

import argparse

import pytest

from negobs_gym.cli.common import non_negative_float, positive_float, task_env_or_exit


def test_positive_float_takes_finite_positive_numbers_only() -> None:
    assert positive_float("0.5") == 0.5
    for bad in ("0", "-1", "nan", "inf"):
        with pytest.raises(argparse.ArgumentTypeError, match="finite number > 0"):
            positive_float(bad)


def test_non_negative_float_takes_zero_but_not_below_or_specials() -> None:
    assert non_negative_float("0") == 0.0 and non_negative_float("1.5") == 1.5
    for bad in ("-0.1", "nan", "inf"):
        with pytest.raises(argparse.ArgumentTypeError, match=">= 0"):
            non_negative_float(bad)


def test_a_bad_env_or_setting_exits_2_naming_it(capsys) -> None:
    parser = argparse.ArgumentParser(prog="bench")
    env = task_env_or_exit(parser, "paper_n_three_pits", "oracle", ["observation.tighten_pairs=false"])
    observation = env.unwrapped.scenario.observation
    assert observation.tighten_pairs is False and observation.source == "oracle"
    env.close()
    for name, overrides in (("paper_n_three_pits", ["observation.tighten=1"]), ("no_such_scene", [])):
        with pytest.raises(SystemExit) as exit_info:
            task_env_or_exit(parser, name, None, overrides)
        assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "observation.tighten: unknown key" in err and "no_such_scene" in err
