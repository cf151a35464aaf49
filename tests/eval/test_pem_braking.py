"""The PEM's closed-loop check: the braking campaign on the detector grid and on the PEM's."""

from __future__ import annotations

import math

import pytest

from negobs_gym.cli import main
from negobs_gym.errors import ConfigError
from negobs_gym.eval.braking_campaign import ConfigurationSummary
from negobs_gym.eval.pem_check import BrakingCheckConfig, compare_braking


def _summary(stopped: int, margins: list[float], first_veto: list[float], episodes: int = 10):
    return ConfigurationSummary(
        name="ditch/reckless/filter",
        obstacle=True,
        episodes=episodes,
        entries=episodes - stopped,
        stopped_before=stopped,
        km=0.5,
        veto_events=stopped,
        false_vetoes_per_km=None,
        stop_margins_m=margins,
        first_veto_gaps_m=first_veto,
    )


def test_compare_braking_checks_stopped_before_counts_and_median_margins():
    config = BrakingCheckConfig(seeds=10)
    detector = _summary(10, [2.0, 2.2, 2.4], [9.0, 10.0])
    close = compare_braking(
        {"detector": [detector], "pem": [_summary(8, [2.1, 2.3, 2.5], [9.5, 10.5])]}, config
    )
    assert close.passed
    assert close.figures["braking_ditch_stopped_before_delta"] == -2.0
    assert close.figures["braking_ditch_stop_margin_median_delta_m"] == pytest.approx(0.1)
    assert close.figures["braking_ditch_first_veto_gap_median_delta_m"] == pytest.approx(0.5)
    fewer = compare_braking({"detector": [detector], "pem": [_summary(7, [2.1], [9.0])]}, config)
    assert not fewer.checks["check_braking_stopped_before"] and fewer.checks["check_braking_stop_margin"]
    later = compare_braking({"detector": [detector], "pem": [_summary(10, [1.9, 1.9, 1.95], [9.0])]}, config)
    assert later.checks["check_braking_stopped_before"] and not later.checks["check_braking_stop_margin"]
    never = compare_braking({"detector": [detector], "pem": [_summary(0, [], [])]}, config)
    assert math.isnan(never.figures["braking_ditch_stop_margin_median_m_pem"]) and not never.passed


def test_braking_check_runs_the_same_campaign_on_both_grids(capsys):
    campaigns = BrakingCheckConfig(seeds=3, overrides=("observation.rig=reduced",)).campaign(None)
    detector, pem = campaigns["detector"], campaigns["pem"]
    assert (
        detector.seeds == pem.seeds == 3 and detector.filters == (True,) and detector.drivers == ("reckless",)
    )
    # each grid named, so a --set of another source cannot turn the detector's run into something else
    assert detector.overrides == ("observation.rig=reduced", "observation.source=detector")
    # no model named: the env draws from the shipped model of its own positive channel
    assert pem.overrides == ("observation.rig=reduced", "observation.source=pem")
    with pytest.raises(ConfigError, match="braking_seeds"):
        BrakingCheckConfig(seeds=0)
    assert main(["pem", "check", "--no-courses"]) != 0
    assert "--no-courses needs --braking-seeds" in capsys.readouterr().err
