"""The braking demo of ``negobs demo`` (and ``python -m negobs_gym``): the filter saves the reckless driver"""

from __future__ import annotations

import math

import pytest

import negobs_gym.demo as demo
from negobs_gym.demo import main, run_demo


@pytest.fixture(scope="module")
def seed_0(tmp_path_factory):
    """The demo of seed 0, driven once: its figure, its two runs and the episodes ``run_episode``
    drove, keyed by (seed, filtered), for the CLI test to replay."""
    out = tmp_path_factory.mktemp("demo") / "demo.png"
    episodes = {}
    drive = demo.run_episode

    def driven_once(seed: int, filtered: bool):
        episodes[seed, filtered] = drive(seed, filtered)
        return episodes[seed, filtered]

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(demo, "run_episode", driven_once)
        runs = run_demo(out, seed=0)
    return out, runs, episodes


def test_demo_filter_stops_before_the_ditch_the_reckless_driver_enters(seed_0):
    out, runs, _ = seed_0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    plain, filtered = (run.result for run in runs)
    assert not plain.filtered and filtered.filtered
    assert plain.start_gap_m == filtered.start_gap_m  # same seed, same ditch
    assert plain.entered_negative_obstacle and plain.vetoes == 0 and plain.first_veto_gap_m is None
    assert not filtered.entered_negative_obstacle and filtered.stopped  # stood 1 s before the ditch
    assert filtered.final_speed_mps < 0.1 and 0.0 < filtered.final_gap_m < 6.0
    # the filter braked before the ditch came within R(25 km/h) of the rear axle (10.52 m, minus
    # the 3.65 m from the rear axle to the bumper) and not absurdly early
    assert filtered.first_veto_gap_m is not None and 6.0 < filtered.first_veto_gap_m < 15.0
    assert runs[0].frame.shape == runs[1].frame.shape and runs[0].frame.ndim == 3
    assert not math.isnan(filtered.final_gap_m)


def test_demo_cli_writes_png_and_rejects_a_negative_seed(seed_0, tmp_path, capsys, monkeypatch):
    """The CLI asks for its seed's two episodes; seed 0's, driven once above, stand in for them."""
    asked = []

    def replayed(seed: int, filtered: bool):
        asked.append((seed, filtered))
        return seed_0[2][0, filtered]

    monkeypatch.setattr(demo, "run_episode", replayed)
    out = tmp_path / "sub" / "demo.png"
    assert main(["--out", str(out), "--seed", "1"]) == 0
    assert asked == [(1, False), (1, True)]
    assert out.stat().st_size > 1000
    with pytest.raises(SystemExit):
        main(["--out", str(out), "--seed", "-1"])
    assert "--seed" in capsys.readouterr().err
