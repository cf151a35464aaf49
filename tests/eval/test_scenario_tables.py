"""write_scenario_tables: a scenario run's results, vetoes and paths as CSV, and the spec as run."""

from __future__ import annotations

import dataclasses
import math

import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.eval.campaign import read_csv
from negobs_gym.eval.scenario_runner import ScenarioResult, run_scenario
from negobs_gym.eval.scenario_tables import PATH_COLUMNS, RESULT_COLUMNS, TABLE_FILES, write_scenario_tables
from negobs_gym.eval.vetoes import VETO_COLUMNS
from negobs_gym.spec import spec_from_toml
from tests.helpers import PIT_SCENE


@pytest.fixture(scope="module")
def spec():
    return spec_from_toml(PIT_SCENE)


@pytest.fixture(scope="module")
def results(spec) -> list[ScenarioResult]:
    """The reckless driver behind the filter towards a 0.6 m deep pit: vetoes on every seed."""
    return [run_scenario(spec, seed=seed) for seed in (3, 4)]


@pytest.fixture(scope="module")
def tables(spec, results, tmp_path_factory) -> dict[str, list[dict[str, str]]]:
    out = tmp_path_factory.mktemp("tables")
    written = write_scenario_tables(out, spec, results)
    assert [p.name for p in written] == list(TABLE_FILES)
    tables = {name: read_csv(out / f"{name}.csv") for name in ("results", "vetoes", "paths")}
    tables["toml"] = (out / "scenario.toml").read_text()
    return tables


def test_results_hold_one_row_per_seed_with_the_results_fields(results, tables) -> None:
    rows = tables["results"]
    assert list(rows[0]) == list(RESULT_COLUMNS)
    keys = [(r["episode"], int(r["seed"])) for r in rows]
    assert keys == [("pit_0.6m_seed3", 3), ("pit_0.6m_seed4", 4)]
    for row, r in zip(rows, results, strict=True):
        assert r.vetoes > 0 and r.stopped_before  # the fixture's premise
        assert (row["filter"], row["driver"], row["passed"]) == ("filter", "reckless", "1")
        assert int(row["steps"]) == r.steps and int(row["vetoes"]) == r.vetoes
        assert int(row["missed_vetoes"]) == r.missed_vetoes and int(row["false_vetoes"]) == r.false_vetoes
        assert float(row["stop_margin_m"]) == pytest.approx(r.stop_margin_m, abs=1e-6)
        assert float(row["max_veto_error_m"]) == pytest.approx(r.max_veto_error_m, abs=1e-6)
        assert float(row["positive_gap_m"]) == math.inf  # no rock
        assert row["termination"] == ";".join(r.termination) == "stopped" and row["failures"] == ""


def test_vetoes_hold_each_judgement_of_each_seed(results, tables) -> None:
    rows = tables["vetoes"]
    assert list(rows[0]) == list(VETO_COLUMNS)
    for r, result_row in zip(results, tables["results"], strict=True):
        mine = [row for row in rows if row["episode"] == f"pit_0.6m_seed{r.seed}"]
        onsets = [int(row["step"]) for row in mine if row["onset"] == "1"]
        assert onsets == [s for s in r.vetoed_steps if s - 1 not in r.vetoed_steps]
        assert len(onsets) == r.veto_events == int(result_row["veto_events"]) >= 1
        assert len(mine) == len(r.veto_judgements) and sum(row["kind"] == "veto" for row in mine) == r.vetoes
        for row, j in zip(mine, r.veto_judgements, strict=True):
            assert int(row["step"]) == j.step
            error = float(row["error_m"])
            assert math.isnan(error) if j.error_m is None else error == pytest.approx(j.error_m, abs=1e-6)


def test_paths_hold_every_position_with_the_vetoed_steps_flagged(results, tables) -> None:
    rows = tables["paths"]
    assert list(rows[0]) == list(PATH_COLUMNS)
    for r in results:
        mine = [row for row in rows if int(row["seed"]) == r.seed]
        assert [int(row["step"]) for row in mine] == list(range(r.steps + 1)) == list(range(len(r.path_xy_m)))
        assert [int(row["step"]) for row in mine if row["vetoed"] == "1"] == list(r.vetoed_steps)
        assert float(mine[-1]["x_m"]) == pytest.approx(r.path_xy_m[-1][0], abs=1e-6)


def test_the_spec_is_written_as_toml_that_loads_back_equal(spec, tables) -> None:
    assert spec_from_toml(tables["toml"]) == spec


def test_a_name_a_csv_cell_cannot_hold_is_refused_before_writing(spec, results, tmp_path) -> None:
    with pytest.raises(ConfigError, match=r"name.*comma"):
        write_scenario_tables(tmp_path / "out", dataclasses.replace(spec, name="pit, wide"), results)
    assert not (tmp_path / "out").exists()
    renamed = [dataclasses.replace(r, driver='my "best" policy') for r in results]  # a driver's name too
    with pytest.raises(ConfigError, match=r"driver: must hold no comma, quote"):
        write_scenario_tables(tmp_path / "out", spec, renamed)
    assert not (tmp_path / "out").exists()
