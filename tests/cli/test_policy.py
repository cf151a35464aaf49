"""``negobs policy list`` and ``show``: the shipped policies from their records."""

import json

from negobs_gym.cli import main
from negobs_gym.drivers.zoo import baseline_names, baseline_record
from negobs_gym.eval.stats import format_interval, rate_interval


def test_list_gives_each_shipped_policy_its_settings_recipe_and_default_grid_figures(capsys) -> None:
    assert main(["policy", "list"]) == 0
    out = capsys.readouterr().out
    heads = [line for line in out.splitlines() if not line.startswith(" ")]
    names = baseline_names()
    assert [line.split()[0] for line in heads] == names
    for name, head in zip(names, heads, strict=True):
        record = baseline_record(name)
        env = head.split()[1]
        assert env.startswith(record["env"])
        assert all(setting in env for setting in record.get("set", ()))  # what eval policy applies
        assert head.endswith(f"recipe: negobs train --recipe {name}")
        figures = record["evaluation"]["default_grid"]
        block = out.split(head + "\n", 1)[1].split("\n")[:3]
        assert block[0].startswith(f"  default grid, seeds {figures['seeds']}: ")
        for key, label in (("nofilter", "no filter"), ("filter", "behind the filter")):
            result = figures[key]
            interval = format_interval(rate_interval(result["goal"], result["episodes"]))
            assert f"{label}: goal {result['goal']}/{result['episodes']} ({interval})," in block[0]
        assert block[1] == f"    grid: {figures['grid']}" and block[2] == f"    command: {figures['command']}"
    clone = next(line for line in heads if line.startswith("bc_offroad_nav_v2_detector "))
    assert "observation.lux_forward_m=3.7" in clone and "cloned, no RL step" in clone
    assert "PPO 100,000 steps" in next(line for line in heads if line.startswith("ppo_offroad_nav_v1 "))
    # the PEM-trained v1 policy on 100 courses of today's grid, either way
    assert (
        "no filter: goal 94/100 (0.88-0.97), entries 0, collisions 3; "
        "behind the filter: goal 94/100 (0.88-0.97), entries 0, collisions 2, vetoes 83" in out
    )


def test_a_figure_the_record_lacks_is_a_dash() -> None:
    from negobs_gym.cli.policy import figures_lines

    assert figures_lines({}) == ["  default grid: not measured"]
    record = {"evaluation": {"default_grid": {"seeds": "1-2", "nofilter": {"episodes": 2, "goal": 1}}}}
    line, grid, command = figures_lines(record)
    assert line.startswith("  default grid, seeds 1-2: no filter: goal 1/2 (")
    assert line.endswith("entries -, collisions -") and grid == "    grid: -" and command == "    command: -"


def test_show_prints_the_record_and_an_unknown_name_exits_naming_the_shipped(capsys) -> None:
    assert main(["policy", "show", "ppo_offroad_nav_v1_pem"]) == 0
    assert json.loads(capsys.readouterr().out) == baseline_record("ppo_offroad_nav_v1_pem")
    assert main(["policy", "show", "ppo_nothing"]) == 2
    err = capsys.readouterr().err
    assert "no shipped baseline 'ppo_nothing'" in err and "ppo_offroad_nav_v1" in err
    assert main(["policy", "show", "ppo_offroad_nav_v2_clone"]) == 2  # retired: what instead
    assert "'ppo_offroad_nav_v2_clone' was retired" in capsys.readouterr().err


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
