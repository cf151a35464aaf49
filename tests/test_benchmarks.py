"""The benchmark harness (negobs_gym.bench, ``negobs bench``): every suite writes its JSON results
file with finite figures, and the docs' tables are generated from such files.

The suites run here at sizes far below ``--quick`` (a frame or a few steps each), so the default
test run stays short; the real ``negobs bench --quick`` is the slow test at the end. No timing
is asserted: only that each figure exists, is finite and has its sign.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest

from negobs_gym.bench import (
    SUITE_NAMES,
    BenchError,
    Figure,
    Suite,
    fill_tables,
    format_value,
    load_suite,
    results_path,
    run_suite,
    write_tables,
)
from negobs_gym.bench.detection import DetectionSize
from negobs_gym.bench.detector import DetectorSize
from negobs_gym.bench.env import ORACLE_ENV, Drive, EnvSize, oracle_and_pem
from negobs_gym.bench.safety import SafetySize
from negobs_gym.cli import main
from negobs_gym.envs import make_env
from negobs_gym.errors import ConfigError

#: Sizes for the tests alone: each measurement runs once on the least input it takes.
TINY = {
    "env": EnvSize(
        steps=3,
        rounds=2,
        round_steps=2,
        vec_steps=2,
        resets=1,
        pool=1,
        pool_resets=2,
        memory_steps=4,
        memory_warmup=2,
        physics_s=1.0,
        courses=1,
        train_steps=64,
        n_steps=32,
    ),
    "detector": DetectorSize(frames=1, dense_frames=1, cluster_rounds=1, cast_repeats=1),
    "detection": DetectionSize(seeds=1, frames=40),  # the fewest frames that see a pit in every bin
    "safety": SafetySize(episodes=1),
}

BINS = ("6_8m", "8_10m", "10_12m", "12_14m", "14_16m", "16_18m", "18_20m")
FIGURES = {
    "env": {
        "env_steps_per_s",
        "step_cpu_ms",
        "cpu_bound_steps_per_s",
        "serial_bound_steps_per_s",
        "two_process_steps_per_s",
        "two_process_over_one",
        "two_process_bound",
        "native_rig_steps_per_s",
        "reduced_rig_steps_per_s",
        "oracle_steps_per_s",
        "pem_steps_per_s",
        "pem_over_oracle",
        "scan_every_4_steps_per_s",
        "scan_every_3_far_8_steps_per_s",
        "reset_new_terrain_s",
        "reset_terrain_pool_s",
        "memory_growth_mb",
        "physics_steps_per_s",
        "course_build_s",
        "ppo_steps_per_s",
        "ppo_pem_steps_per_s",
        *(f"stage_{stage}_ms" for stage in ("physics", "scan", "paper_n", "paper_t", "other")),
    },
    "detector": {
        "native_frame_ms",
        "roi_frame_ms",
        "native_cast_ms",
        "paper_n_update_ms",
        "paper_t_update_ms",
        "cluster_ms",
        "dense_update_ms",
        "dense_cluster_ms",
        "raycast_ms",
        "speedup_vs_pybullet",
        "raycast_agreement",
    },
    "detection": {f"{mode}_recall_{b}" for mode in ("fused", "hdl64", "hdl32") for b in BINS}
    | {
        "false_alarms_per_frame",
        "false_alarms_per_km",
        "false_alarms_per_km_on_track",
        "false_alarms_per_km_off_track",
    },
    "safety": {
        "stop_distance_m",
        "ditch_stopped_pct",
        "ditch_margin_m",
        "trench_narrow_stopped_pct",
        "trench_narrow_margin_m",
    },
}
# Figures that may legitimately be 0: a recall (no pit recalled in a far bin of a short drive) and
# false alarms (none in a clean drive). memory_growth_mb may have either sign (memory handed back).
MAY_BE_ZERO = ("_recall_", "false_alarms_")
ANY_SIGN = {"memory_growth_mb"}
RESULT_KEYS = {"suite", "quick", "code_version", "machine", "wall_s", "cpu_s", "peak_rss_mb", "figures"}


def check_results(path: Path, suite: str) -> dict:
    """The results file's content after checking its layout and every figure's sign."""
    results = json.loads(path.read_text())
    assert set(results) == RESULT_KEYS
    assert results["suite"] == suite
    assert set(results["machine"]) == {"cpu", "cores", "python", "numpy", "platform", "load_average"}
    assert results["code_version"].startswith("0.")
    assert results["wall_s"] > 0 and results["cpu_s"] > 0 and results["peak_rss_mb"] > 0
    assert set(results["figures"]) == FIGURES[suite]
    for key, figure in results["figures"].items():
        assert set(figure) == {"value", "unit", "what"} and figure["what"], key
        value = figure["value"]
        assert math.isfinite(value), key
        if key in ANY_SIGN:
            continue
        if any(part in key for part in MAY_BE_ZERO):
            assert value >= 0, key
        else:
            assert value > 0, key
    return results


# the env suite builds ~10 envs and a PPO run's workers even at its least size (over a minute), and
# the safety suite drives whole braking episodes: slow; the default run checks the other two
@pytest.mark.parametrize(
    "suite", [pytest.param(s, marks=pytest.mark.slow) if s in ("env", "safety") else s for s in SUITE_NAMES]
)
def test_each_suite_writes_its_results_file(suite: str, tmp_path: Path) -> None:
    path, results = run_suite(
        load_suite(suite), quick=True, out_dir=tmp_path, size=TINY[suite], progress=False
    )
    assert path == tmp_path / f"{suite}.quick.json"
    assert check_results(path, suite) == results
    assert results["quick"] is True


def test_oracle_and_pem_rates_come_from_alternating_rounds_on_the_same_steps() -> None:
    """The two envs drive the same courses step for step (a constant action, the same seeds), so
    each round of one is paired with the other's; the ratio is the rounds' median, not the rates'."""
    size = dataclasses.replace(TINY["env"], rounds=3, round_steps=2)
    figures = oracle_and_pem(size)
    assert set(figures) == {"oracle_steps_per_s", "pem_steps_per_s", "pem_over_oracle"}
    assert figures["pem_over_oracle"].unit == "x" and "3 rounds" in figures["pem_over_oracle"].what
    assert all(f.value > 0 for f in figures.values())
    envs = [make_env(ORACLE_ENV, (f"observation.source={s}",)) for s in ("oracle", "pem")]
    drives = [Drive(env) for env in envs]
    for _ in range(2):
        clocks = [d.steps(3) for d in drives]
        assert [c.blocks for c in clocks] == [3, 3]
    poses = [env.unwrapped._vehicle.true_pose() for env in envs]
    assert poses[0] == poses[1] and drives[0].seed == drives[1].seed
    for env in envs:
        env.close()


def test_a_suite_takes_only_its_own_size() -> None:
    with pytest.raises(BenchError, match="DetectorSize"):
        load_suite("detector").run(size=TINY["safety"])
    with pytest.raises(ConfigError, match="frames"):
        DetectorSize(frames=0, dense_frames=1, cluster_rounds=1, cast_repeats=1)
    with pytest.raises(BenchError, match="unknown suite 'nosuch'"):
        load_suite("nosuch")


def test_a_figure_is_finite() -> None:
    with pytest.raises(BenchError, match="finite"):
        Figure(math.nan, "ms", "a timing")
    assert Figure(3, "ms", "a timing").value == 3.0


def fake_suite(**values: float) -> Suite:
    """A suite of one measurement that reports ``values`` (key -> value, unit ms)."""

    def measure(size: DetectorSize) -> dict[str, Figure]:
        return {key: Figure(v, "ms", f"the {key}") for key, v in values.items()}

    size = TINY["detector"]
    return Suite(name="fake", what="a test suite", full=size, quick=size, measurements=(measure,))


def test_quick_and_full_runs_write_apart(tmp_path: Path) -> None:
    run_suite(fake_suite(a=1.0), quick=False, out_dir=tmp_path, progress=False)
    run_suite(fake_suite(a=2.0), quick=True, out_dir=tmp_path, progress=False)
    assert json.loads(results_path(tmp_path, "fake", False).read_text())["figures"]["a"]["value"] == 1.0
    assert json.loads(results_path(tmp_path, "fake", True).read_text())["figures"]["a"]["value"] == 2.0


DOC = """# Page

Some prose.

<!-- bench-table: fake b,a -->
stale rows
<!-- /bench-table -->

More prose.

<!-- bench-table: fake -->
<!-- /bench-table -->
"""


def test_tables_are_generated_from_the_results(tmp_path: Path) -> None:
    run_suite(fake_suite(a=1234.56, b=0.08312), out_dir=tmp_path, progress=False)
    filled = fill_tables(DOC, tmp_path)
    assert "stale rows" not in filled
    assert filled.startswith("# Page\n\nSome prose.\n\n<!-- bench-table: fake b,a -->\n")
    header = "| figure | value | command |\n|---|---|---|\n"
    first = "| the b | 0.0831 ms | `negobs bench fake` |\n| the a | 1,235 ms | `negobs bench fake` |\n"
    assert header + first + "<!-- /bench-table -->\n\nMore prose." in filled
    every = "<!-- bench-table: fake -->\n" + header + "| the a | 1,235 ms | `negobs bench fake` |\n"
    assert every + "| the b | 0.0831 ms | `negobs bench fake` |\n<!-- /bench-table -->\n" in filled
    assert fill_tables(filled, tmp_path) == filled  # idempotent


def test_a_qualified_key_takes_its_figure_from_another_suite(tmp_path: Path) -> None:
    run_suite(fake_suite(a=1.0), out_dir=tmp_path, progress=False)
    other = dataclasses.replace(fake_suite(a=2.0), name="other")
    run_suite(other, quick=True, out_dir=tmp_path, progress=False)
    filled = fill_tables("<!-- bench-table: fake a,other.a -->\n<!-- /bench-table -->\n", tmp_path)
    rows = "| the a | 1.00 ms | `negobs bench fake` |\n| the a | 2.00 ms | `negobs bench other --quick` |\n"
    assert rows + "<!-- /bench-table -->" in filled
    with pytest.raises(BenchError, match=r"figure 'b' is not in .*other\.quick\.json"):
        fill_tables("<!-- bench-table: fake other.b -->\n<!-- /bench-table -->\n", tmp_path)


def test_a_quick_result_serves_where_no_full_one_exists(tmp_path: Path) -> None:
    run_suite(fake_suite(a=5.0), quick=True, out_dir=tmp_path, progress=False)
    assert "| the a | 5.00 ms | `negobs bench fake --quick` |" in fill_tables(
        DOC.replace("b,a", "a"), tmp_path
    )


def test_a_missing_key_or_file_or_end_is_an_error_that_names_it(tmp_path: Path) -> None:
    run_suite(fake_suite(a=1.0), out_dir=tmp_path, progress=False)
    with pytest.raises(BenchError, match=r"'b' is not in .*fake\.json"):
        fill_tables(DOC, tmp_path)
    with pytest.raises(BenchError, match=r"no results file .*other\.json"):
        fill_tables("<!-- bench-table: other -->\n<!-- /bench-table -->\n", tmp_path)
    with pytest.raises(BenchError, match="not closed"):
        fill_tables("<!-- bench-table: fake a -->\n| row |\n", tmp_path)


def test_format_value_keeps_three_significant_digits() -> None:
    assert format_value(34.94, "steps/s") == "34.9 steps/s"
    assert format_value(0.0, "") == "0"
    assert format_value(299.4, "x") == "299 x"
    assert format_value(-7.46, "MB") == "-7.46 MB"


def test_negobs_bench_tables_rewrites_readme_and_docs(tmp_path: Path, capsys) -> None:
    results = tmp_path / "results"
    run_suite(fake_suite(a=1.0, b=2.0), out_dir=results, progress=False)
    (tmp_path / "docs").mkdir()
    readme, page = tmp_path / "README.md", tmp_path / "docs" / "page.md"
    readme.write_text(DOC)
    page.write_text("no table here\n")
    argv = ["bench", "--tables", "--root", str(tmp_path), "--out", str(results)]
    assert main(argv) == 0
    filled = readme.read_text()
    assert filled == fill_tables(DOC, results) and page.read_text() == "no table here\n"
    assert main(argv) == 0 and readme.read_text() == filled  # a second run changes nothing
    readme.write_text(DOC.replace("b,a", "b,c"))
    assert main(argv) == 2  # one line naming the key and the file, no traceback
    assert write_tables([page], results) == []


def test_negobs_bench_names_an_unknown_suite(tmp_path: Path) -> None:
    assert main(["bench", "nosuch", "--out", str(tmp_path)]) == 2
    assert not list(tmp_path.iterdir())


@pytest.mark.slow
def test_negobs_bench_quick_runs_every_suite(tmp_path: Path) -> None:
    assert main(["bench", "--quick", "--out", str(tmp_path)]) == 0
    for suite in SUITE_NAMES:
        check_results(tmp_path / f"{suite}.quick.json", suite)
