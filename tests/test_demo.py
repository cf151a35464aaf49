"""The quick-start demo (``python -m negobs_gym``): brakes before the ditch and writes its PNG."""

from __future__ import annotations

import pytest

from negobs_gym.demo import DEMO_SPEED_MPS, main, run_braking_demo


def test_demo_stops_before_the_ditch(tmp_path):
    result = run_braking_demo(out_path=tmp_path / "demo.png", seed=0)
    assert result.image_path is not None
    assert result.image_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert result.brake_speed_mps == pytest.approx(DEMO_SPEED_MPS, rel=0.03)
    ideal = result.brake_speed_mps**2 / (2 * 0.65 * 9.81)
    assert result.stop_distance_m == pytest.approx(ideal, rel=0.15)  # rough ground: within ~8 %
    assert not result.entered_ditch
    # brake 15 m before the ditch, minus at most one 0.05 s sample of travel, minus the stop distance
    assert 15.0 - 0.4 - result.stop_distance_m <= result.margin_m <= 15.0 - result.stop_distance_m + 0.05
    assert result.path_xy_m.shape[1] == 2 and len(result.path_xy_m) > 20


def test_demo_cli_writes_png_and_rejects_a_too_close_ditch(tmp_path, capsys):
    out = tmp_path / "sub" / "demo.png"
    assert main(["--out", str(out), "--seed", "1", "--ditch-distance", "25"]) == 0
    assert out.stat().st_size > 1000
    with pytest.raises(SystemExit):
        main(["--out", str(out), "--ditch-distance", "10"])
    assert "ditch_distance_m" in capsys.readouterr().err
