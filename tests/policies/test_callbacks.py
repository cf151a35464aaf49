"""EvalCallback: one eval.csv row per evaluation, summed (or the largest) over its episodes."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

from stable_baselines3.common.logger import configure

from negobs_gym.eval.campaign import read_csv
from negobs_gym.policies.callbacks import EVAL_COLUMNS, EvalCallback


def _episode(vetoes: int, false: int, missed: int, error: float) -> dict:
    return {
        "goal": False, "entered": missed > 0, "collision": False, "rollover": False, "trapped": False,
        "off_track_steps": 0, "progress_m": 40.0, "vetoes": vetoes, "false_vetoes": false,
        "missed_vetoes": missed, "max_veto_error_m": error, "cost": 1.0,
    }  # fmt: skip


def test_each_evaluation_writes_a_row_of_its_episodes(tmp_path: Path) -> None:
    evaluations = iter(
        [
            [_episode(6, 0, 0, -0.2), _episode(9, 1, 4, 1.75), _episode(0, 0, 0, math.nan)],
            [_episode(0, 0, 0, math.nan)],  # no veto: no error to give
        ]
    )
    callback = EvalCallback(lambda model: next(evaluations), tmp_path / "eval.csv", every=100)
    callback.init_callback(SimpleNamespace(get_env=lambda: None, logger=configure(None, []), num_timesteps=0))
    first = callback.run()
    counts = [first[k] for k in ("episodes", "vetoes", "false_vetoes", "missed_vetoes")]
    assert counts == [3, 15, 1, 4]
    assert first["entries"] == 1 and first["max_veto_error_m"] == 1.75  # the largest, not a sum
    callback.run()
    rows = read_csv(tmp_path / "eval.csv")
    assert tuple(rows[0]) == EVAL_COLUMNS and len(rows) == 2
    assert float(rows[0]["max_veto_error_m"]) == 1.75 and math.isnan(float(rows[1]["max_veto_error_m"]))
