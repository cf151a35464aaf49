"""The learning-curve figure reads negobs train's logs and evaluations."""

from __future__ import annotations

from pathlib import Path

from negobs_gym.eval.plots import learning_curves_plot


def _run(folder: Path, returns: list[float]) -> Path:
    (folder / "logs" / "0").mkdir(parents=True)
    lines = ["time/total_timesteps,rollout/ep_rew_mean", "512,"]
    lines += [f"{1024 * (k + 1)},{r}" for k, r in enumerate(returns)]
    (folder / "logs" / "0" / "progress.csv").write_text("\n".join(lines) + "\n")
    (folder / "eval.csv").write_text("step,episodes,goal\n1024,4,1\n2048,4,3\n")
    return folder


def test_learning_curves_png_from_run_folders(tmp_path: Path) -> None:
    runs = {"a": _run(tmp_path / "a", [-50.0, 10.0]), "b": _run(tmp_path / "b", [-70.0, -60.0])}
    runs["empty"] = tmp_path / "none"  # a folder without logs is skipped
    out = learning_curves_plot(runs, tmp_path / "curves.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 5_000
