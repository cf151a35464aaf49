"""``negobs policy list`` and ``show``: the shipped policies from their records."""

import json

from negobs_gym.cli import main
from negobs_gym.drivers.zoo import baseline_names, baseline_record
from negobs_gym.eval.stats import format_interval, rate_interval


def test_list_gives_each_shipped_policy_its_env_settings_and_recorded_result(capsys) -> None:
    assert main(["policy", "list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names = baseline_names()
    assert len(names) >= 8 and [line.split()[0] for line in lines] == names
    for name, line in zip(names, lines, strict=True):
        record = baseline_record(name)
        env = line.split()[1]
        assert env.startswith(record["env"])
        assert all(setting in env for setting in record.get("set", ()))  # what eval policy applies
        result = record["evaluation"]["nofilter"]
        interval = format_interval(rate_interval(result["goal"], result["episodes"]))
        assert f"goal {result['goal']}/{result['episodes']} ({interval})," in line
    detector = next(line for line in lines if line.startswith("ppo_offroad_nav_v2_detector_clone "))
    assert "observation.lux_forward_m=2.0" in detector and "cloned, no RL step" in detector
    assert "PPO 100,000 steps" in next(line for line in lines if line.startswith("ppo_offroad_nav_v1 "))
    # 45 and 53 goals of 100 for the two oracle-grid clones: intervals that overlap
    assert "goal 53/100 (0.43-0.62)" in next(
        line for line in lines if line.startswith("ppo_offroad_nav_v2_clone_160k ")
    )


def test_show_prints_the_record_and_an_unknown_name_exits_naming_the_shipped(capsys) -> None:
    assert main(["policy", "show", "ppo_offroad_nav_v1_detector_filter"]) == 0
    assert json.loads(capsys.readouterr().out) == baseline_record("ppo_offroad_nav_v1_detector_filter")
    assert main(["policy", "show", "ppo_nothing"]) == 2
    err = capsys.readouterr().err
    assert "no shipped baseline 'ppo_nothing'" in err and "ppo_offroad_nav_v1" in err


def test_show_prints_a_model_files_own_record(tmp_path, capsys) -> None:
    import zipfile

    from negobs_gym.drivers.zoo import FITTED_ON, fitted_on_record

    record = fitted_on_record("negobs_gym/OffroadTrack-v0", ["observation.tighten_pairs=false"])
    model = tmp_path / "policy.zip"
    with zipfile.ZipFile(model, "w") as archive:  # SB3's layout: the model's JSON attributes in "data"
        archive.writestr("data", json.dumps({"gamma": 0.99, FITTED_ON: record}))
    assert main(["policy", "show", str(model)]) == 0
    assert json.loads(capsys.readouterr().out) == record
    assert main(["policy", "show", str(tmp_path / "policy")]) == 0  # SB3 adds .zip itself
    assert json.loads(capsys.readouterr().out) == record
    with zipfile.ZipFile(model, "w") as archive:
        archive.writestr("data", json.dumps({"gamma": 0.99}))
    assert main(["policy", "show", str(model)]) == 2
    assert "holds no record of the env it was fitted on" in capsys.readouterr().err
