"""The campaign runner: deterministic text, atomic parts, resume, identical CSVs on every backend."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from negobs_gym.errors import ConfigError, MissingDependencyError
from negobs_gym.eval.campaign import (
    Backend,
    Episode,
    assemble_csv,
    format_row,
    format_value,
    import_ray,
    read_csv,
    run_episodes,
)


def noisy_episode(episode: Episode) -> dict[str, list[str]]:
    """A cheap seeded episode: three rows of floats from the seed (module level: picklable)."""
    rng = np.random.default_rng(episode.args["seed"])
    return {"rows": [format_row([episode.key, k, float(rng.normal())]) for k in range(3)]}


def _episodes(n: int) -> list[Episode]:
    return [Episode(f"e{seed:03d}", {"seed": seed}) for seed in range(n)]


def test_format_value_is_fixed_and_spells_out_specials() -> None:
    assert format_value(1.0 / 3.0) == "0.333333"
    assert format_value(-0.0) == "0.000000"
    assert format_value(-1e-9) == "0.000000"  # rounds to zero: no "-0.000000"
    assert format_value(math.nan) == "nan"
    assert format_value(-math.inf) == "-inf"
    assert format_value(True) == "1" and format_value(np.int64(7)) == "7"
    with pytest.raises(ConfigError, match=r"^csv_value: 'a,b' holds a comma") as comma:
        format_value("a,b")
    assert comma.value.field == "csv_value" and isinstance(comma.value, ValueError)


def test_episode_keys_must_be_file_names_and_unique(tmp_path) -> None:
    with pytest.raises(ConfigError, match="key"):
        Episode("a/b")
    with pytest.raises(ConfigError, match="unique"):
        run_episodes(noisy_episode, [Episode("x", {"seed": 0})] * 2, tmp_path, progress=False)
    with pytest.raises(ConfigError, match="workers"):
        Backend(workers=0)


def test_csv_rows_sorted_by_key_whatever_the_finish_order(tmp_path) -> None:
    eps = _episodes(4)
    results = run_episodes(noisy_episode, eps[::-1], tmp_path, progress=False)
    csv = assemble_csv(results, "rows", ["episode", "k", "x"], tmp_path / "out.csv")
    rows = read_csv(csv)
    assert [r["episode"] for r in rows] == [e.key for e in eps for _ in range(3)]
    assert sorted(p.stem for p in (tmp_path / "parts").glob("*.json")) == [e.key for e in eps]


def test_workers_give_the_same_bytes_as_serial(tmp_path) -> None:
    eps = _episodes(5)
    texts = []
    for name, backend in (("serial", Backend()), ("two", Backend(workers=2))):
        results = run_episodes(noisy_episode, eps, tmp_path / name, backend=backend, progress=False)
        texts.append(
            assemble_csv(results, "rows", ["episode", "k", "x"], tmp_path / f"{name}.csv").read_bytes()
        )
    assert texts[0] == texts[1]


def test_resume_skips_finished_parts_and_clears_temp_files(tmp_path) -> None:
    eps = _episodes(4)
    run_episodes(noisy_episode, eps[:2], tmp_path, progress=False)
    parts = tmp_path / "parts"
    stamps = {p.name: p.stat().st_mtime_ns for p in parts.glob("*.json")}
    (parts / ".e002.json.abc.tmp").write_text("half")  # what a kill mid-write leaves
    calls: list[str] = []

    def counting(episode: Episode) -> dict[str, list[str]]:
        calls.append(episode.key)
        return noisy_episode(episode)

    results = run_episodes(counting, eps, tmp_path, resume=True, progress=False)
    assert calls == ["e002", "e003"]
    assert {p.name: p.stat().st_mtime_ns for p in parts.glob("e00[01].json")} == stamps
    assert not list(parts.glob(".*.tmp"))
    fresh = run_episodes(noisy_episode, eps, tmp_path / "fresh", progress=False)
    assert results == fresh
    # without --resume the parts are cleared: everything runs again
    calls.clear()
    run_episodes(counting, eps, tmp_path, progress=False)
    assert calls == [e.key for e in eps]


def test_resume_with_other_settings_is_a_clear_error(tmp_path) -> None:
    eps = [Episode(f"e{seed:03d}", {"seed": seed, "tighten_pairs": False}) for seed in range(2)]
    run_episodes(noisy_episode, eps, tmp_path, progress=False)
    changed = [Episode(e.key, {**e.args, "tighten_pairs": True}) for e in eps]
    want = r"parts/e000.json.*tighten_pairs: kept False, asked True.*without resume"
    with pytest.raises(ConfigError, match=want):
        run_episodes(noisy_episode, changed, tmp_path, resume=True, progress=False)
    # the same settings resume; a config dataclass is compared by its fields
    cfg = Backend(workers=2)
    kept = [Episode(e.key, {**e.args, "backend": cfg}) for e in eps]
    run_episodes(noisy_episode, kept, tmp_path / "c", progress=False)
    assert run_episodes(noisy_episode, kept, tmp_path / "c", resume=True, progress=False)
    with pytest.raises(ConfigError, match="backend: kept"):
        other = [Episode(e.key, {**e.args, "backend": Backend(workers=3)}) for e in eps]
        run_episodes(noisy_episode, other, tmp_path / "c", resume=True, progress=False)


def test_missing_ray_is_a_clear_error(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(MissingDependencyError, match=r"negobs_gym\[ray\]"):
        import_ray()


def test_a_kept_part_with_other_columns_is_a_clear_error(tmp_path) -> None:
    # a part resumed from a campaign whose table had one column fewer (another version)
    results = {"e000": {"rows": ["e000,0,0.5"]}, "e001": {"rows": ["e001,0"]}}
    with pytest.raises(ConfigError, match=r"rows\[e001\].*2 fields, the table's header 3.*without resume"):
        assemble_csv(results, "rows", ["episode", "k", "x"], tmp_path / "out.csv")
    assert not (tmp_path / "out.csv").exists()
    # a part kept from a version whose episodes wrote no such table: an error, not missing rows
    results = {"e000": {"rows": ["e000,0,0.5"], "more": []}, "e001": {"rows": ["e001,0,0.7"]}}
    assert assemble_csv(results, "rows", ["episode", "k", "x"], tmp_path / "rows.csv").is_file()
    with pytest.raises(ConfigError, match=r"parts/e001.json.*no 'more' table.*without resume"):
        assemble_csv(results, "more", ["episode"], tmp_path / "more.csv")
    assert not (tmp_path / "more.csv").exists()
