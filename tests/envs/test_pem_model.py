"""The PEM's parameters and file: round trip, the shipped model, refused settings and files."""

from __future__ import annotations

import dataclasses
import json

import pytest

from negobs_gym.envs.pem import (
    DEFAULT_PEM_PATH,
    SHIPPED_PEM_PATHS,
    TERRAIN_CLASSES,
    PemParameters,
    PerceptionErrorModel,
    load_pem,
    pem_settings,
    shipped_pem_path,
)
from negobs_gym.errors import ConfigError
from negobs_gym.spec import ObservationConfig, load_scenario
from negobs_gym.spec.observation import POSITIVE_DETECTORS


def constant_parameters(p: float, near: float = 0.0, far: float = 0.0, density: float = 0.0) -> PemParameters:
    """Tables that draw every obstacle from its first sighting on (``p`` = 1) or none (0), with
    fixed edge offsets and ``density`` false alarms per m² on every terrain class (4-cell blobs)."""
    d_edges, s_edges, levels = (0.0, 10.0, 30.0), (0.0, 10_000.0), (0.0, 1.0)
    confirm = 100.0 if p > 0 else -1.0
    return PemParameters(
        distance_edges_m=d_edges,
        size_edges_cells=s_edges,
        quantile_levels=levels,
        confirm_distance_m=((confirm, confirm),),
        confirm_latency_frames=(0.0, 0.0),
        approach_m=22.0,
        loss_distance_m=(),
        p_keep=((p, p),),
        p_return=((p, p),),
        sightings=((1, 1),),
        near_offset_m=((near, near), (near, near)),
        far_offset_m=((far, far), (far, far)),
        fa_density_per_m2=tuple((density, density) for _ in TERRAIN_CLASSES),
        fa_area_m2=tuple(1.0 for _ in TERRAIN_CLASSES),
        fa_keep=tuple((0.5, 0.5) for _ in TERRAIN_CLASSES),
        fa_blobs=((1.0, 0.0, 0.5, 2.0, 2.0, 4.0),),
        border_band_m=1.0,
        clutter_band_m=2.0,
        rough_relief_m=0.2,
        match_cells=0,
    )


def constant_model(
    p: float, near: float = 0.0, far: float = 0.0, density: float = 0.0, positive: float | None = None
) -> PerceptionErrorModel:
    """A PEM of :func:`constant_parameters` on the ``negative`` channel, and with ``positive`` given
    on the ``positive`` channel too (there drawn with probability ``positive``, no offsets)."""
    pos = constant_parameters(positive) if positive is not None else None
    channels = ("negative", "positive") if pos is not None else ("negative",)
    return PerceptionErrorModel(
        parameters=constant_parameters(p, near, far, density),
        positive=pos,
        fitted_on=pem_settings(ObservationConfig(), channels),
    )


def test_shipped_pem_loads_for_the_default_observation():
    model = load_pem(None, ObservationConfig())
    assert DEFAULT_PEM_PATH.is_file()
    assert model.fitted_on == pem_settings(ObservationConfig())
    assert model.fit["frames"] >= 100
    assert model.channels == ("negative", "positive")
    assert PerceptionErrorModel.from_json(model.to_json()) == model


def test_a_model_ships_for_each_positive_channel_and_is_picked_by_it():
    assert set(SHIPPED_PEM_PATHS) == set(POSITIVE_DETECTORS)
    structure = load_scenario("offroad_nav_v2_structure").observation
    assert structure.positive_detector == "structure"
    assert shipped_pem_path(structure) != shipped_pem_path(ObservationConfig()) == DEFAULT_PEM_PATH
    model = load_pem(None, structure)  # the structure channel's file, not the default's
    assert model.fitted_on == pem_settings(structure)
    assert model.channels == ("negative", "positive")
    with pytest.raises(ConfigError, match="positive_detector"):
        load_pem(DEFAULT_PEM_PATH, structure)


def test_a_positive_model_is_refused_for_other_lux_settings_a_negative_one_is_not(tmp_path):
    both = constant_model(0.5, positive=0.5).save(tmp_path / "both.json")
    negative = constant_model(0.5).save(tmp_path / "negative.json")
    moved = dataclasses.replace(ObservationConfig(), lux_forward_m=2.0)
    with pytest.raises(ConfigError, match=r"observation\.lux_forward_m"):
        load_pem(both, moved)
    with pytest.raises(ConfigError, match=r"observation\.positive_detector"):
        load_pem(both, dataclasses.replace(ObservationConfig(), positive_detector="structure"))
    assert load_pem(negative, moved).channels == ("negative",)
    assert PerceptionErrorModel.from_json(both.read_text()).positive == constant_parameters(0.5)
    data = json.loads(both.read_text())
    del data["positive_parameters"]
    with pytest.raises(ConfigError, match="positive_parameters"):
        PerceptionErrorModel.from_json(json.dumps(data))
    with pytest.raises(ConfigError, match="channel"):
        PerceptionErrorModel.from_json(negative.read_text()).channel_parameters("positive")


def test_files_fitted_on_other_settings_or_layouts_are_refused(tmp_path):
    path = constant_model(0.5).save(tmp_path / "pem.json")
    with pytest.raises(ConfigError, match=r"observation\.rig"):
        load_pem(path, dataclasses.replace(ObservationConfig(), rig="reduced"))
    with pytest.raises(ConfigError, match=r"detector\.fusion\.tighten_on_match"):
        load_pem(path, dataclasses.replace(ObservationConfig(), tighten_pairs=False))
    data = json.loads(path.read_text())
    data["version"] = 99
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="version 99"):
        load_pem(path, ObservationConfig())
    with pytest.raises(ConfigError, match="no PEM file"):
        load_pem(tmp_path / "missing.json", ObservationConfig())


def test_a_model_fitted_on_another_detector_default_is_refused_by_name(tmp_path):
    """A detector default that changed after the fit (here paper N's detector without the HDL-64
    ground checks) makes the file unusable until refitted; the error names each field."""
    model = constant_model(0.5)
    fitted_on = dict(model.fitted_on)
    fitted_on["detector.hdl64_ground_checks.crest_rise_m"] = float("inf")
    fitted_on["detector.some_removed_field"] = 1.0
    path = dataclasses.replace(model, fitted_on=fitted_on).save(tmp_path / "old.json")
    with pytest.raises(ConfigError) as error:
        load_pem(path, ObservationConfig())
    assert error.value.field == "observation.pem_model"
    assert "detector.hdl64_ground_checks.crest_rise_m (fitted on inf, now" in str(error.value)
    assert "detector.some_removed_field (fitted on 1.0, now '<absent>')" in str(error.value)
    assert "Refit it" in str(error.value)


def test_bad_parameters_are_refused():
    good = constant_model(0.5).parameters
    with pytest.raises(ConfigError, match="p_keep"):
        dataclasses.replace(good, p_keep=((1.5, 0.5),))
    with pytest.raises(ConfigError, match="near_offset_m"):
        dataclasses.replace(good, near_offset_m=((0.5, 0.1), (0.0, 0.0)))
    with pytest.raises(ConfigError, match="fa_blobs"):
        dataclasses.replace(good, fa_blobs=((99.0, 0.0, 0.5, 2.0, 2.0, 4.0),))
    with pytest.raises(ConfigError, match="source"):
        ObservationConfig(source="pems")
