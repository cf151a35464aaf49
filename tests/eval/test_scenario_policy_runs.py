"""A trained policy as a scenario's driver (``run.policy``): the episode ``negobs eval policy``
drives, bit for bit, in one process or several."""

from __future__ import annotations

import pytest

from negobs_gym.cli import main
from negobs_gym.drivers.model import ModelDriver
from negobs_gym.errors import ConfigError
from negobs_gym.eval.campaign import format_value, read_csv
from negobs_gym.eval.scenario_runner import run_scenario, run_scenario_seeds
from negobs_gym.spec import load_scenario
from negobs_gym.spec.overrides import apply_overrides

SETTINGS = ["episode.time_limit_s=2", "run.policy=ppo_offroad_nav_v1"]
#: OffroadNav-v1's shortest course: its world builds ~4x faster
SHORT_COURSE = "terrain.params.length_m=60"


@pytest.fixture(scope="module")
def spec():
    """OffroadNav-v1's scenario on a 60 m course for 2 s (20 steps), the shipped v1 policy driving
    behind the filter."""
    return apply_overrides(load_scenario("offroad_nav_v1"), [*SETTINGS, SHORT_COURSE])


def test_the_policy_drives_the_episode_eval_policy_drives(spec, tmp_path) -> None:
    args = "-q eval policy ppo_offroad_nav_v1 --env negobs_gym/OffroadNav-v1 --seeds 1 --first-seed 7"
    args = [*args.split(), "--filter", "on", "--set", SETTINGS[0], "--set", SHORT_COURSE]
    args += ["--out", str(tmp_path), "--no-progress"]
    assert main(args) == 0
    result = run_scenario(spec, seed=7, filter=True)
    assert result.driver == "ppo_offroad_nav_v1" and result.steps == 20
    recorded = [(row["x_m"], row["y_m"]) for row in read_csv(tmp_path / "paths.csv")]
    assert [(format_value(x), format_value(y)) for x, y in result.path_xy_m] == recorded
    assert result.path_xy_m[-1][1] - result.path_xy_m[0][1] > 2.0  # it drove off


# slow (end to end): a model driver in worker processes; the policy driving a scenario is checked
# by test_the_policy_drives_the_episode_eval_policy_drives
@pytest.mark.slow
def test_a_model_driver_reaches_worker_processes_as_its_path(spec) -> None:
    driver = ModelDriver("ppo_offroad_nav_v1")
    serial = [run_scenario(spec, driver, seed=s) for s in (3, 4)]
    assert list(run_scenario_seeds(spec, driver, (3, 4), workers=2)) == serial
    assert run_scenario(spec, None, seed=4) == serial[1]  # run.policy: the same driver as the path
    assert {r.driver for r in serial} == {"ppo_offroad_nav_v1"}


def test_an_observation_the_policy_was_not_trained_on_is_named() -> None:
    spec = apply_overrides(load_scenario("paper_n_mud_pit"), SETTINGS)  # a 4-channel grid, v1 saw 2
    with pytest.raises(ConfigError, match=r"policy: the env's observation does not fit ppo_offroad_nav_v1's"):
        run_scenario(spec, seed=0)


def test_a_spec_file_reads_its_policy_beside_it(tmp_path, monkeypatch) -> None:
    from negobs_gym.drivers.zoo import resolve_model
    from negobs_gym.spec import spec_to_toml

    suite = tmp_path / "suite"
    (suite / "models").mkdir(parents=True)
    (suite / "models" / "mine.zip").write_bytes(open(resolve_model("ppo_offroad_nav_v1"), "rb").read())
    for name, policy in [
        ("beside", "models/mine.zip"),
        ("stem", "models/mine"),
        ("shipped", "ppo_offroad_nav_v1"),
    ]:
        text = spec_to_toml(apply_overrides(load_scenario("offroad_nav_v1"), [f"run.policy={policy}"]))
        (suite / f"{name}.toml").write_text(text)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # the models do not lie under the working directory
    assert load_scenario(suite / "beside.toml").run.policy == str(suite / "models" / "mine.zip")
    assert load_scenario(suite / "stem.toml").run.policy == str(suite / "models" / "mine")
    assert load_scenario(suite / "shipped.toml").run.policy == "ppo_offroad_nav_v1"  # a name stays one
    # a path to no model beside the file stays as written (read from the working directory)
    (elsewhere / "models").mkdir()
    (elsewhere / "models" / "other.zip").write_bytes(b"")
    text = spec_to_toml(apply_overrides(load_scenario("offroad_nav_v1"), ["run.policy=models/other.zip"]))
    (suite / "cwd.toml").write_text(text)
    assert load_scenario(suite / "cwd.toml").run.policy == "models/other.zip"
    # the CLI runs the suite's spec from here (it refused a model it could not find: exit 2)
    run = ["-q", "scenario", "run", str(suite / "beside.toml"), "--seeds", "1"]
    assert main([*run, "--set", "episode.time_limit_s=0.3", "--out", str(tmp_path / "out")]) == 0
    assert read_csv(tmp_path / "out" / "results.csv")[0]["driver"] == str(suite / "models" / "mine.zip")
