"""PEM fit and check: the tables from hand-made rows, the comparison's verdicts, a small round trip."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from negobs_gym.cli import main
from negobs_gym.envs.pem import TERRAIN_CLASSES, load_pem
from negobs_gym.errors import ConfigError
from negobs_gym.eval.campaign import RunOptions, format_row, read_csv
from negobs_gym.eval.pem_check import PemCheckConfig, check_pem, compare
from negobs_gym.eval.pem_data import (
    AREA_COLUMNS,
    FRAME_COLUMNS,
    JUDGE_VERSION,
    SIGHTING_COLUMNS,
    SPURIOUS_COLUMNS,
    PemCampaignConfig,
)
from negobs_gym.eval.pem_fit import calibrate, calibration_factors, fit_parameters, fit_pem
from negobs_gym.spec import ObservationConfig


def _write(path, header, rows):
    path.write_text("\n".join([",".join(header), *rows]) + "\n")
    return path


def _sighting(mode, frame, obstacle, centre_m, detected, near=0.0, episode="seed0", cells=25):
    drawn = 30 if detected else 0
    offsets = (near, 0.1) if detected else (np.nan, np.nan)
    return format_row([episode, 0, frame, mode, obstacle, cells, 0.8, centre_m, detected, drawn, *offsets])


def _frame(mode, frame, fa_on=0, fa_off=0, area=1.0, episode="seed0"):
    return format_row([episode, 0, frame, mode, 1.0, fa_on, fa_off, *([area] * len(AREA_COLUMNS))])


def test_fit_reads_the_chain_confirmations_offsets_and_false_alarm_rates(tmp_path):
    # ten pits from 24 m in, each first drawn at 15.5 m and after that every other frame
    sightings = []
    for pit in range(10):
        for f in range(20):
            centre = 24.0 - 0.5 * f
            hit = centre <= 15.5 and f % 2 == 1
            sightings.append(_sighting("detector", f, pit, centre, hit, near=-0.4, episode=f"seed{pit}"))
    # ten pits first seen at 12 m, drawn from their third frame on
    sightings += [
        _sighting("detector", f, 0, 12.0 - 0.5 * f, f >= 2, episode=f"near{k}")
        for k in range(10)
        for f in range(6)
    ]
    frames = [_frame("detector", f, area=100.0) for f in range(200)]
    spurious = [
        format_row(
            ["seed0", 0, f, "detector", "verge", 0.3, 9.0, 6, 3, 2, True, f % 4 != 0, "", "", 0.0, 9.0]
        )
        for f in range(200)
    ]
    params = _fit(tmp_path, sightings, spurious, frames)
    s = 2  # 25 cells: the 25-34 bin (fewer than 20 confirmations: all sizes' quantiles)
    assert params.confirm_distance_m[s][10] == pytest.approx(15.75)  # between 16 m and the drawn 15.5 m
    assert params.confirm_latency_frames[10] == 2.0
    assert params.p_keep[s][7] < 0.1  # never twice in a row (14-16 m)
    assert params.p_return[s][7] > 0.9  # always back after a miss
    assert params.near_offset_m[s][7][10] == pytest.approx(-0.4)
    # 200 blobs in 200 frames over 100 m² of the verge class at 8-10 m: 0.01 per frame per m²
    assert params.fa_density_per_m2[1][4] == pytest.approx(0.01, rel=0.01)
    assert params.fa_density_per_m2[0][4] == 0.0
    assert params.fa_keep[1][4] == pytest.approx(0.75, abs=0.02)  # kept 3 frames in 4 at 8-10 m
    assert params.fa_blobs[0] == (1.0, 4.0, 0.3, 3.0, 2.0, 6.0)


def test_blobs_beside_a_pits_rim_are_its_fragments_not_false_alarms(tmp_path):
    """With ``fragment_m``, a blob touching no pit but centred within that distance of a rim is
    left out of the false-alarm tables (density, persistence and the blob library); without it,
    or farther out, it is a false alarm. Rows without ``pit_m`` are refused, naming it."""
    frames = [_frame("detector", f, area=100.0) for f in range(200)]

    def blob(f, pit_m):  # the verge class at 8-10 m, kept 3 frames in 4
        return format_row(
            ["seed0", 0, f, "detector", "verge", 0.3, 9.0, 6, 3, 2, True, f % 4 != 0, "", pit_m, 0.0, 9.0]
        )

    spurious = [blob(f, 0.4 if f % 2 else "") for f in range(200)]  # every other one a fragment
    sightings = [_sighting("detector", 0, 0, 10.0, True)]
    every = _fit(tmp_path, sightings, spurious, frames)
    paths = [
        _write(tmp_path / n, h, r)
        for n, h, r in (("s.csv", SIGHTING_COLUMNS, sightings), ("sp.csv", SPURIOUS_COLUMNS, spurious),
                        ("f.csv", FRAME_COLUMNS, frames))
    ]  # fmt: skip
    cut = fit_parameters(*paths, 1.0, 2.0, 0.2, fragment_m=1.0)
    assert every.fa_density_per_m2[1][4] == pytest.approx(0.01, rel=0.01)
    assert cut.fa_density_per_m2[1][4] == pytest.approx(0.005, rel=0.02)  # the 100 beyond 1 m of a pit
    assert len(cut.fa_blobs) == 100 and len(every.fa_blobs) == 200
    assert fit_parameters(*paths, 1.0, 2.0, 0.2, fragment_m=0.3).fa_blobs == every.fa_blobs  # 0.4 m out
    old = [",".join(r.split(",")[:13] + r.split(",")[14:]) for r in spurious]  # no pit_m column
    header = [c for c in SPURIOUS_COLUMNS if c != "pit_m"]
    with pytest.raises(ConfigError, match="pit_fragment_m"):
        PemCampaignConfig(pit_fragment_m=5.0)  # beyond the 3 m the rows record pit_m within
    with pytest.raises(ConfigError, match="pit_m"):
        fit_parameters(
            paths[0], _write(tmp_path / "old.csv", header, old), paths[2], 1.0, 2.0, 0.2, fragment_m=1.0
        )


def test_edge_offsets_are_fitted_per_size_and_thin_bins_borrow_their_sizes(tmp_path):
    """Small obstacles drawn a cell before their face, large ones only from their far side (the
    structure channel's rocks and mounds): each size bin keeps its own offsets at every distance."""
    sightings = [
        _sighting(
            "detector", f, k, 6.0 + 0.5 * (f % 28), True, near=near, episode=f"{cells}_{k}", cells=cells
        )
        for cells, near in ((12, -0.2), (300, 1.2))
        for k in range(4)
        for f in range(30)
    ]
    sightings += [_sighting("detector", 0, 9, 19.0, True, near=5.0, episode="lone", cells=40)]
    params = _fit(tmp_path, sightings, [], [_frame("detector", f, area=100.0) for f in range(10)])
    small, lone, large = 0, 3, 5  # the size bins of 12, 40 and 300 cells
    assert np.asarray(params.near_offset_m).shape[:2] == (6, len(params.distance_edges_m) - 1)
    median = len(params.quantile_levels) // 2
    edges = np.asarray(params.distance_edges_m)
    for at_m in (6.5, 12.5, 18.5, 25.0):  # the last: no hit that far, its size's over all distances
        d = int(np.searchsorted(edges, at_m, side="right") - 1)
        assert params.near_offset_m[small][d][median] == pytest.approx(-0.2)
        assert params.near_offset_m[large][d][median] == pytest.approx(1.2)
    # one hit of its size: too few, so its distance bin's hits of all sizes
    d = int(np.searchsorted(edges, 19.0, side="right") - 1)
    lo, hi = edges[d], edges[d + 1]
    there = [float(r.split(",")[10]) for r in sightings if lo <= float(r.split(",")[7]) < hi]
    assert len(set(there)) == 3  # small, large and the lone one
    assert params.near_offset_m[lone][d] == pytest.approx(np.quantile(there, params.quantile_levels))
    # a model with one table per distance bin (no size axis) still loads and serves every size
    flat = dataclasses.replace(params, near_offset_m=params.near_offset_m[small])
    assert np.asarray(flat.near_offset_m).ndim == 2


def _fit(tmp_path, sightings, spurious, frames):
    """:func:`fit_parameters` of the rows, written as the fit's three CSVs."""
    return fit_parameters(
        _write(tmp_path / "s.csv", SIGHTING_COLUMNS, sightings),
        _write(tmp_path / "sp.csv", SPURIOUS_COLUMNS, spurious),
        _write(tmp_path / "f.csv", FRAME_COLUMNS, frames),
        border_band_m=1.0,
        clutter_band_m=2.0,
        rough_relief_m=0.2,
    )


def _frame_by_class(frame, areas, episode="seed0"):
    """A detector frame row with ``areas[class]`` m² in every distance bin of each class."""
    per_column = [areas.get(column.split("_")[1], 0.0) for column in AREA_COLUMNS]
    return format_row([episode, 0, frame, "detector", 1.0, 0, 0, *per_column])


def test_false_alarm_rates_are_fitted_per_terrain_class_and_unseen_classes_borrow(tmp_path):
    """Clutter ground with five times the smooth ground's false alarms per m² gets five times its
    rate; bank, drop-off and rough ground, never driven, take the smooth ground's, a mound's the
    clutter's (and show 0 m² fitted)."""
    areas = {"track": 40.0, "verge": 10.0, "smooth": 20.0, "clutter": 4.0}
    frames = [_frame_by_class(f, areas) for f in range(300)]
    spurious = []
    for f in range(300):  # 8-10 m: smooth 20 m² x 0.01 = 0.2 per frame, clutter 4 m² x 0.05 = 0.2
        if f % 5 == 0:
            spurious.append(
                format_row(
                    ["seed0", 0, f, "detector", "smooth", 3.0, 9.0, 4, 2, 2, False, False, "", "", 6.0, 9.0]
                )
            )
        if f % 5 == 1:
            spurious.append(
                format_row(
                    [
                        "seed0",
                        0,
                        f,
                        "detector",
                        "clutter",
                        1.2,
                        9.0,
                        6,
                        3,
                        2,
                        False,
                        f > 100,
                        0.7,
                        "",
                        4.2,
                        9.0,
                    ]
                )
            )
    sightings = [_sighting("detector", 0, 0, 10.0, True)]
    params = _fit(tmp_path, sightings, spurious, frames)
    k = {c: i for i, c in enumerate(TERRAIN_CLASSES)}
    density = np.asarray(params.fa_density_per_m2)
    # 60 blobs over 300 frames x 20 m² (smooth) and 4 m² (clutter) in the 8-10 m bin, shrunk a little
    assert density[k["smooth"], 4] == pytest.approx(0.01, rel=0.02)
    assert density[k["clutter"], 4] == pytest.approx(0.05, rel=0.05)
    assert density[k["clutter"], 4] / density[k["smooth"], 4] == pytest.approx(5.0, rel=0.05)
    assert density[k["clutter"], 9] < 0.01 * density[k["clutter"], 4]  # none seen at 18-20 m
    for name in ("bank", "dropoff", "rough"):
        assert np.array_equal(density[k[name]], density[k["smooth"]]) and params.fa_area_m2[k[name]] == 0.0
    assert np.array_equal(density[k["mound"]], density[k["clutter"]]) and params.fa_area_m2[k["mound"]] == 0.0
    assert params.fa_area_m2[k["bank"]] == 0.0 and params.fa_area_m2[k["clutter"]] == pytest.approx(
        4.0 * 14 * 300
    )
    assert (
        max(params.fa_keep[k["clutter"]]) > 0.0 and params.fa_keep[k["bank"]] == params.fa_keep[k["smooth"]]
    )
    assert params.clutter_band_m == 2.0 and params.rough_relief_m == 0.2
    assert {blob[0] for blob in params.fa_blobs} == {k["smooth"], k["clutter"]}


def test_calibration_factors_bring_the_recall_per_bin_to_the_detectors(tmp_path):
    """At 8-10 m the detector draws 20 of 40 sightings and the PEM 32: that bin's chain is scaled
    by 0.625; 10-12 m, seen 10 times, too few to say, keeps 1, as does a bin seen by neither."""
    sightings = [_sighting("detector", f, 0, 9.0, f < 20) for f in range(40)]
    sightings += [_sighting("pem", f, 0, 9.0, f < 32) for f in range(40)]
    sightings += [_sighting(m, 50 + f, 1, 11.0, f < 5) for m in ("detector", "pem") for f in range(10)]
    s_csv = _write(tmp_path / "s.csv", SIGHTING_COLUMNS, sightings)
    edges = tuple(float(e) for e in range(0, 30, 2))
    by_bin = calibration_factors(s_csv, edges)
    assert by_bin[4] == pytest.approx(20 / 32) and by_bin[5] == 1.0 and by_bin[0] == 1.0
    with pytest.raises(ConfigError, match="no pem sighting"):
        calibration_factors(_write(tmp_path / "d.csv", SIGHTING_COLUMNS, sightings[:40]), edges)


def test_calibrate_scales_the_chain_per_bin_and_nothing_else():
    params = load_pem(None, ObservationConfig()).positive
    by_bin = np.ones(len(params.distance_edges_m) - 1)
    by_bin[3], by_bin[4] = 0.5, 3.0
    out = calibrate(params, by_bin)
    keep, new_keep = np.asarray(params.p_keep), np.asarray(out.p_keep)
    assert np.allclose(new_keep[:, 3], keep[:, 3] * 0.5, atol=1e-6)
    assert np.allclose(new_keep[:, 4], np.minimum(keep[:, 4] * 3.0, 1.0), atol=1e-6)  # a share stays <= 1
    assert np.array_equal(new_keep[:, 5:], keep[:, 5:]) and out.p_return != params.p_return
    assert dataclasses.replace(out, p_keep=params.p_keep, p_return=params.p_return) == params


def test_compare_passes_equal_grids_and_fails_each_kind_of_difference(tmp_path):
    rng = np.random.default_rng(0)
    centres = rng.uniform(6.0, 20.0, 400)
    hits = rng.random(400) < 0.8
    rows = {
        m: [
            _sighting(m, k, k, float(c), bool(h), near=-0.3)
            for k, (c, h) in enumerate(zip(centres, hits, strict=True))
        ]
        for m in ("detector", "pem")
    }
    frames = [_frame(m, f, fa_on=f % 5 == 0, fa_off=1) for m in ("detector", "pem") for f in range(100)]
    same = compare(
        _write(tmp_path / "s.csv", SIGHTING_COLUMNS, rows["detector"] + rows["pem"]),
        _write(tmp_path / "f.csv", FRAME_COLUMNS, frames),
    )
    assert same.passed and same.figures["ks_first_confirmation"] == 0.0
    assert same.figures["false_alarms_on_track_count_pem"] == 20.0  # every fifth of 100 frames
    assert all(line.count("=") == 1 for line in same.lines()) and same.lines()[-1] == "pem_check=pass"
    # the PEM misses every third pit
    worse = [
        _sighting("pem", k, k, float(c), bool(h) and k % 3 != 0, near=-0.3)
        for k, (c, h) in enumerate(zip(centres, hits, strict=True))
    ]
    fewer_fa = [
        _frame(m, f, fa_on=0 if m == "pem" else f % 5 == 0, fa_off=1)
        for m in ("detector", "pem")
        for f in range(100)
    ]
    result = compare(
        _write(tmp_path / "s2.csv", SIGHTING_COLUMNS, rows["detector"] + worse),
        _write(tmp_path / "f2.csv", FRAME_COLUMNS, fewer_fa),
    )
    assert not result.checks["check_recall"]
    assert not result.checks["check_false_alarms_on_track"] and result.checks["check_false_alarms_off_track"]
    assert result.lines()[-1] == "pem_check=fail"
    late = [
        _sighting("pem", k, k, float(c), bool(h), near=0.0)
        for k, (c, h) in enumerate(zip(centres, hits, strict=True))
    ]
    edge = compare(_write(tmp_path / "s3.csv", SIGHTING_COLUMNS, rows["detector"] + late), tmp_path / "f.csv")
    assert not edge.checks["check_near_edge"] and edge.checks["check_recall"]
    loose = compare(tmp_path / "s3.csv", tmp_path / "f.csv", PemCheckConfig(max_near_edge_delta_m=0.5))
    assert loose.passed


def test_fit_then_check_round_trip_on_a_few_frames(tmp_path, capsys):
    model_path = tmp_path / "pem.json"
    fit = PemCampaignConfig(seeds=1, frames=6)
    model = fit_pem(fit, model_path, tmp_path / "fit")
    assert load_pem(model_path, ObservationConfig()) == model  # written, and valid for the default grid
    assert sum(map(sum, model.parameters.sightings)) > 0
    assert model.channels == ("negative", "positive") and sum(map(sum, model.positive.sightings)) > 0
    with pytest.raises(ConfigError, match="used to fit"):
        check_pem(model, PemCampaignConfig(seeds=1, frames=6), tmp_path / "bad")
    out = tmp_path / "check"
    code = main(
        ["pem", "check", "--model", str(model_path), "--out", str(out), "--seeds", "1", "--frames", "6",
         "--first-seed", "500", "--no-progress"]
    )  # fmt: skip
    printed = capsys.readouterr().out.strip().splitlines()
    assert printed == (out / "check.txt").read_text().strip().splitlines()
    verdict = dict(line.split("=") for line in printed)
    assert code == (0 if verdict["pem_check"] == "pass" else 1)
    assert float(verdict["frames_pem"]) == 6.0 and float(verdict["frames_detector"]) == 6.0
    assert float(verdict["positive_frames_pem"]) == 6.0 and "check_positive_recall" in verdict
    written = {p.name for p in out.iterdir()}
    assert {"tables.md", "summary.json", "pem_check.png", "sightings.csv"} <= written
    assert {"pem_check_positive.png", "positive_sightings.csv", "positive_frames.csv"} <= written
    # the PEM's drive is its own episode on the detector's true poses
    frames = read_csv(out / "frames.csv")
    travelled = {m: [r["travelled_m"] for r in frames if r["mode"] == m] for m in ("detector", "pem")}
    assert travelled["detector"] == travelled["pem"] and len(travelled["pem"]) == 6
    # a check of another model resumed into the same folder keeps the detector's drive
    parts = out / "parts"
    detector_part = parts / "seed0000500.json"
    kept = detector_part.stat().st_mtime_ns
    other = dataclasses.replace(model, positive=dataclasses.replace(model.positive, match_cells=0))
    check_pem(
        other,
        PemCampaignConfig(seeds=1, frames=6, first_seed=500),
        out,
        options=RunOptions(resume=True, progress=False),
    )
    assert detector_part.stat().st_mtime_ns == kept
    assert len(list(parts.glob("seed0000500-pem-*.json"))) == 2
    # a drive judged by other rules is refused on resume, naming the judge's version
    record = json.loads(detector_part.read_text())
    record["args"]["judge"] = JUDGE_VERSION - 1
    detector_part.write_text(json.dumps(record))
    with pytest.raises(ConfigError, match="judge"):
        check_pem(
            other, PemCampaignConfig(seeds=1, frames=6, first_seed=500), out,
            options=RunOptions(resume=True, progress=False),
        )  # fmt: skip


def test_a_calibrated_fit_drives_its_own_courses_with_the_pem_and_records_the_passes(tmp_path):
    fit = PemCampaignConfig(seeds=1, frames=6)
    work = tmp_path / "fit"
    plain = fit_pem(fit, tmp_path / "plain.json", work, calibration_passes=0)
    with pytest.raises(ConfigError, match="calibration_passes"):
        fit_pem(fit, tmp_path / "bad.json", work, calibration_passes=-1)
    resume = RunOptions(resume=True, progress=False)
    model = fit_pem(fit, tmp_path / "pem.json", work, resume, calibration_passes=1)
    assert model.fit["calibration_passes"] == 1 and "calibration_passes" not in plain.fit
    assert len(list((work / "parts").glob("seed0000000-pem-*.json"))) == 1  # the pass's drive, resumable
    assert {r["mode"] for r in read_csv(work / "positive_sightings.csv")} == {"detector", "pem"}
    # what the pass changes is the chain, nothing else the tables set
    for channel in model.channels:
        a, b = plain.channel_parameters(channel), model.channel_parameters(channel)
        assert dataclasses.replace(b, p_keep=a.p_keep, p_return=a.p_return) == a
    assert load_pem(tmp_path / "pem.json", ObservationConfig()) == model


ONE_BLOB = (0.0, 0.0, 0.5, 1.0, 1.0, 1.0)  # class, distance bin, edge_m, rows, cols, cells


def test_a_fit_into_a_base_model_replaces_only_its_false_alarm_tables(tmp_path, capsys):
    """``--false-alarms-into BASE``: BASE's chain, offsets and calibration stay; the false-alarm
    tables of both channels are the fit's; the record names both fits; other settings are refused."""
    fit = PemCampaignConfig(seeds=1, frames=6)
    work = tmp_path / "fit"
    plain = fit_pem(fit, tmp_path / "plain.json", work, calibration_passes=0)
    assert plain.parameters.fa_blobs != (ONE_BLOB,)
    base = dataclasses.replace(
        plain,
        parameters=dataclasses.replace(plain.parameters, fa_blobs=(ONE_BLOB,), p_keep=((0.5,) * 14,) * 6),
        positive=dataclasses.replace(plain.positive, fa_blobs=(ONE_BLOB,)),
        fit={**plain.fit, "calibration_passes": 3},
    )
    base_path = base.save(tmp_path / "base.json")
    code = main(
        ["pem", "fit", "--model", str(tmp_path / "merged.json"), "--work", str(work), "--seeds", "1",
         "--frames", "6", "--false-alarms-into", str(base_path), "--resume", "--no-progress"]
    )  # fmt: skip
    assert code == 0 and "calibration_passes=3" in capsys.readouterr().out
    merged = load_pem(tmp_path / "merged.json", ObservationConfig())
    for channel in ("negative", "positive"):
        got, want = merged.channel_parameters(channel), plain.channel_parameters(channel)
        assert got.fa_blobs == want.fa_blobs and got.fa_density_per_m2 == want.fa_density_per_m2
        assert got.p_keep == base.channel_parameters(channel).p_keep
    assert merged.fit["calibration_passes"] == 3 and merged.fit["false_alarms"]["frames"] == 6
    other = dataclasses.replace(base, fitted_on={**base.fitted_on, "observation.scan_every": 2})
    with pytest.raises(ConfigError, match="scan_every"):
        fit_pem(fit, tmp_path / "x.json", work, RunOptions(resume=True, progress=False), 0, other)
    with pytest.raises(ConfigError, match="calibration_passes"):
        fit_pem(fit, tmp_path / "x.json", work, RunOptions(resume=True, progress=False), 1, base)


def test_the_courses_put_rocks_and_boxes_on_the_track_clear_of_the_pits():
    from negobs_gym.eval.detection_campaign import detection_course_obstacles

    config = PemCampaignConfig()
    pits, _ = detection_course_obstacles(config.course, 3, 200.0)
    added = config.track_obstacles(3, 200.0, tuple(pits))
    assert len(added) >= 6 and {a.kind for a in added} == {"rock", "box"}
    for a in added:
        assert 1.9 <= abs(a.lateral_m) <= 2.6
        assert all(abs(a.station_m - p.station_m) >= 3.0 or p.lateral_m * a.lateral_m < 0 for p in pits)
    assert config.track_obstacles(3, 200.0, tuple(pits)) == added  # the seed's layout
    assert PemCampaignConfig(track_obstacles_per_100m=0.0).track_obstacles(3, 200.0, ()) == []
    with pytest.raises(ConfigError, match="track_obstacle_lateral_m"):
        PemCampaignConfig(track_obstacle_lateral_m=(2.0, 1.0))


def test_no_more_false_alarms_are_kept_into_a_bin_than_its_rate_holds(tmp_path):
    """A blob at 8.5 m every frame, always seen the frame before, none nearer: at 1 m a frame the
    survivors head into the 6-8 m bin, which holds none, so nothing is kept into it (the LUX's
    alarms end at ~8 m), while the 8-10 m bin keeps them."""
    frames = [_frame("detector", f, area=100.0) for f in range(200)]
    spurious = [
        format_row(["seed0", 0, f, "detector", "verge", 0.3, 8.5, 6, 3, 2, False, True, "", "", 0.0, 8.5])
        for f in range(200)
    ]
    sightings = [_sighting("detector", f, 0, 24.0 - 0.5 * f, f > 4) for f in range(20)]
    params = _fit(tmp_path, sightings, spurious, frames)
    verge = TERRAIN_CLASSES.index("verge")
    assert params.fa_keep[verge][3] < 0.01  # 6-8 m
    assert params.fa_density_per_m2[verge][4] == pytest.approx(0.01, rel=0.01)


def test_the_pem_episodes_key_names_the_model_and_the_pem_code(monkeypatch, tmp_path):
    """A resumed check reruns the PEM's drives after a refit or a change of the PEM's code."""
    from negobs_gym.envs import pem
    from negobs_gym.eval.pem_data import pem_digest

    assert pem_digest("model a") == pem_digest("model a") != pem_digest("model b")
    other = tmp_path / "pem.py"
    other.write_text("# another version of the PEM's code\n")
    before = pem_digest("model a")
    monkeypatch.setattr(pem, "__file__", str(other))
    assert pem_digest("model a") != before
