"""The package's errors survive a process boundary as themselves (campaign and scenario workers)."""

from __future__ import annotations

import pickle

import pytest

from negobs_gym import errors
from negobs_gym.eval.replay import ReplayMismatch
from negobs_gym.eval.scenario_runner import run_scenario_seeds
from negobs_gym.spec import spec_from_toml

EXAMPLES = [
    errors.ConfigError("depth_m", "must be > 0, got -1"),
    errors.MissingDependencyError("imageio-ffmpeg", "episode videos"),
    errors.ScanError("ranges hold inf"),
    errors.ActionError("action must be finite"),
    errors.GeometryError("polygon needs 3 points"),
    errors.SimulationError("world closed"),
    errors.UsageError("open the video first"),
    errors.ResetNeeded("call reset() first"),
    errors.WorkerError("a worker failed: Traceback ..."),
    errors.InterfaceError("no hazard_state()"),
    errors.UnknownNameError("no mount 'roof'"),
    ReplayMismatch("episode 1.0000001 differs"),
]


def test_every_error_class_has_an_example() -> None:
    classes = {c for c in vars(errors).values() if isinstance(c, type) and issubclass(c, errors.NegobsError)}
    assert classes - {errors.NegobsError} <= {type(e) for e in EXAMPLES}


@pytest.mark.parametrize("error", EXAMPLES, ids=lambda e: type(e).__name__)
def test_an_error_pickles_back_to_itself(error: errors.NegobsError) -> None:
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error) and str(back) == str(error) and vars(back) == vars(error)


def test_a_config_error_in_a_worker_process_reaches_the_caller_as_itself(tmp_path) -> None:
    spec = spec_from_toml('name = "plain"\n[terrain.course]\nlength_m = 30.0\n')
    # the draw window is checked by run_scenario, inside each worker
    seeds = run_scenario_seeds(spec, "reckless", [0, 1], workers=2, draw_dir=tmp_path, draw_zoom_m=-1.0)
    with pytest.raises(errors.ConfigError, match="draw_zoom_m: must be finite and > 0"):
        list(seeds)
