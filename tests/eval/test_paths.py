"""A policy campaign's paths.csv, `negobs eval paths` (the drives over their terrains) and `negobs eval
video` (episodes replayed into MP4s, checked against the record)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.drivers.zoo import resolve_model
from negobs_gym.eval.campaign import read_csv
from negobs_gym.eval.paths import episode_outcome
from negobs_gym.eval.replay import ReplayMismatch, replay_videos


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    """The shipped v1 policy for 2 s (20 steps) of one OffroadNav-v1 course, without and with the
    filter; the shortest course (60 m), so each replay's world builds ~4x faster."""
    out = tmp_path_factory.mktemp("policy")
    args = ["-q", "eval", "policy", "ppo_offroad_nav_v1", "--env", "negobs_gym/OffroadNav-v1", "--seeds", "1"]
    args += ["--set", "episode.time_limit_s=2", "--set", "terrain.params.length_m=60"]
    args += ["--filter", "both", "--out", str(out), "--no-progress"]
    assert main(args) == 0
    return out


def test_paths_hold_every_step_of_every_episode(campaign: Path) -> None:
    episodes = read_csv(campaign / "policy.csv")
    paths = read_csv(campaign / "paths.csv")
    assert len(episodes) == 2
    for episode in episodes:
        rows = [r for r in paths if r["episode"] == episode["episode"]]
        assert [int(r["step"]) for r in rows] == list(range(int(episode["steps"]) + 1))  # the reset first
        assert {r["filter"] for r in rows} == {episode["filter"]} and {r["seed"] for r in rows} == {
            episode["seed"]
        }
        xy = np.array([[float(r["x_m"]), float(r["y_m"])] for r in rows])
        driven = float(np.hypot(*np.diff(xy, axis=0).T).sum())
        assert driven == pytest.approx(float(episode["distance_m"]), abs=1e-4 * len(rows))
        assert sum(r["vetoed"] == "1" for r in rows) == int(episode["vetoes"])
        assert sum(r["missed_veto"] == "1" for r in rows) == int(episode["missed_vetoes"])
        assert float(rows[-1]["speed_mps"]) > 0.5  # the policy drives off within the 2 s


def test_eval_paths_draws_the_episodes(campaign: Path, tmp_path: Path, capsys) -> None:
    assert main(["-q", "eval", "paths", str(campaign)]) == 0  # default: episodes without the goal
    written = capsys.readouterr().out.split()
    keys = sorted(r["episode"] for r in read_csv(campaign / "policy.csv"))
    assert written == [str(campaign / "paths" / f"{k}.png") for k in keys]
    assert all(Path(p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in written)
    assert (
        main(["-q", "eval", "paths", str(campaign), "--episode", keys[1], "--to", str(tmp_path / "one")]) == 0
    )
    assert sorted(p.name for p in (tmp_path / "one").iterdir()) == [f"{keys[1]}.png"]
    zoom = [
        "-q",
        "eval",
        "paths",
        str(campaign),
        "--episode",
        keys[1],
        "--zoom",
        "6",
        "--to",
        str(tmp_path / "z"),
    ]
    assert main(zoom) == 0  # the 12 m square around where the drive ended
    assert mpimg.imread(tmp_path / "z" / f"{keys[1]}.png").shape[:2] == (1000, 1000)
    with pytest.raises(SystemExit) as exit_info:  # argparse: must be > 0
        main(["eval", "paths", str(campaign), "--zoom", "0"])
    assert exit_info.value.code == 2
    assert "must be a finite number > 0" in capsys.readouterr().err
    assert main(["eval", "paths", str(campaign), "--episode", "9.9999999"]) == 2
    assert "no episodes ['9.9999999']" in capsys.readouterr().err
    assert main(["eval", "paths", str(tmp_path)]) == 2
    assert "no policy.csv" in capsys.readouterr().err


def test_eval_paths_draws_a_campaign_from_before_missed_vetoes(
    campaign: Path, tmp_path: Path, capsys
) -> None:
    old = tmp_path / "old"
    shutil.copytree(campaign, old, ignore=shutil.ignore_patterns("paths", "videos"))
    lines = (old / "paths.csv").read_text().splitlines()
    assert lines[0].endswith(",vetoed,missed_veto")
    (old / "paths.csv").write_text("\n".join(line.rsplit(",", 1)[0] for line in lines) + "\n")
    assert main(["-q", "eval", "paths", str(old), "--all"]) == 0  # drawn without crosses
    assert len(capsys.readouterr().out.split()) == 2


def test_an_outcome_names_every_failure_or_the_goal() -> None:
    row = dict.fromkeys(("entered", "collision", "rollover", "trapped", "left_track", "goal"), "0")
    assert episode_outcome(row) == "no goal"
    assert episode_outcome({**row, "goal": "1"}) == "goal"
    assert episode_outcome({**row, "entered": "1", "left_track": "1"}) == "entered + left_track"


def test_eval_video_replays_the_recorded_episode_and_checks_it(
    campaign: Path, tmp_path: Path, capsys
) -> None:
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    rows = read_csv(campaign / "policy.csv")
    key = next(r["episode"] for r in rows if r["filter"] == "filter")
    out = tmp_path / "videos"
    assert main(["-q", "eval", "video", str(campaign), "--episode", key, "--to", str(out)]) == 0
    assert capsys.readouterr().out.split() == [str(out / f"{key}.mp4")]
    reader = imageio_ffmpeg.read_frames(str(out / f"{key}.mp4"))
    next(reader)
    steps = int(next(r["steps"] for r in rows if r["episode"] == key))
    assert sum(1 for _ in reader) == steps + 1  # the reset's frame and one per step
    # a record that the replay does not reproduce: an error, and no video of another episode
    tampered = tmp_path / "tampered"
    shutil.copytree(campaign, tampered, ignore=shutil.ignore_patterns("paths", "videos"))
    part = tampered / "parts" / f"{key}.json"
    record = json.loads(part.read_text())
    record["rows"]["paths"][5] = record["rows"]["paths"][5].replace(",5,", ",5,9", 1)  # step 5's x
    part.write_text(json.dumps(record))
    with pytest.raises(ReplayMismatch, match=r"paths.csv rows differ .* at row 5"):
        replay_videos(tampered, [key], out_dir=tmp_path / "v2")
    assert not list((tmp_path / "v2").iterdir())
    del record["args"]  # a part from before the arguments were recorded
    part.write_text(json.dumps(record))
    assert main(["eval", "video", str(tampered), "--episode", key]) == 2
    assert "does not record the episode's arguments" in capsys.readouterr().err
    assert main(["eval", "video", str(tmp_path)]) == 2
    assert "no policy.csv" in capsys.readouterr().err


def test_eval_video_finds_a_moved_model_with_model(campaign: Path, tmp_path: Path, capsys) -> None:
    """--model: the model where it lies now; another model's replay is refused as a mismatch."""
    pytest.importorskip("imageio_ffmpeg")
    key = next(r["episode"] for r in read_csv(campaign / "policy.csv") if r["filter"] == "filter")
    moved = tmp_path / "moved"  # the campaign of a saved model that has moved since
    shutil.copytree(campaign, moved, ignore=shutil.ignore_patterns("paths", "videos"))
    part = moved / "parts" / f"{key}.json"
    record = json.loads(part.read_text())
    record["args"]["model_path"] = str(tmp_path / "gone" / "model.zip")
    part.write_text(json.dumps(record))
    args = ["eval", "video", str(moved), "--episode", key, "--to", str(tmp_path / "v")]
    assert main(args) == 2
    assert "no saved model at" in capsys.readouterr().err
    shipped = Path(resolve_model("ppo_offroad_nav_v1"))
    model = tmp_path / "models" / "mine.zip"
    model.parent.mkdir()
    shutil.copy(shipped, model)
    assert main(["-q", *args, "--model", str(model)]) == 0
    assert capsys.readouterr().out.split() == [str(tmp_path / "v" / f"{key}.mp4")]
    other = resolve_model("ppo_offroad_nav_v1_pem")  # the same spaces, other weights
    with pytest.raises(ReplayMismatch):
        replay_videos(moved, [key], out_dir=tmp_path / "v2", model=other)
    assert main([*args, "--model", str(tmp_path / "nothing.zip")]) == 2
    assert "model: no saved model at" in capsys.readouterr().err
