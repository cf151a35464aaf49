"""Trained policies shipped with the package (``negobs_gym/drivers/trained/NAME.zip``).

Each ``NAME.zip`` is a stable-baselines3 model saved by ``negobs train``; ``NAME.json`` beside it
records the exact command, seed, steps, wall time, the code and grid it was fitted on, the config
its recipe recreates it with (``negobs train --recipe NAME``) and the evaluations measured on it
(docs/training.md). ``negobs eval policy NAME`` and :func:`resolve_model` accept a baseline's
name wherever a model path is asked for. A name starts with what trained it: ``bc_`` a
behaviour clone with no RL step, ``ppo_`` PPO.
"""

from __future__ import annotations

import json
import warnings
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from negobs_gym.errors import ConfigError
from negobs_gym.spec import recorded_env_in

__all__ = [
    "BASELINE_DIR",
    "FITTED_ON",
    "RENAMED",
    "RETIRED",
    "baseline_names",
    "baseline_record",
    "fitted_on_record",
    "recorded_env",
    "resolve_model",
    "shipped_name",
]

BASELINE_DIR = Path(__file__).with_name("trained")
#: The model attribute ``negobs train`` sets before every save: stable-baselines3 writes a model's
#: JSON-able attributes into the zip's ``data`` member, so the record travels with the file.
FITTED_ON = "negobs_fitted_on"


#: Shipped policies renamed, old name -> new: the old one still works, with a FutureWarning, for
#: one release.
RENAMED: dict[str, str] = {"ppo_offroad_nav_v2_detector_clone_lux_bumper": "bc_offroad_nav_v2_detector"}
#: Policies no longer shipped -> what to use instead. Their records and figures are in
#: docs/notebook/training.md: behaviour clones whose recipe was superseded, and a fine-tuning on a
#: detector grid whose defaults have since changed.
RETIRED: dict[str, str] = {
    "ppo_offroad_nav_v1_detector_filter": "use ppo_offroad_nav_v1_pem, trained on the PEM of today's "
    "default detector grid behind the filter; this one was fine-tuned on an older detector grid "
    "(paper N's fusion history, LUX 2.0 m ahead of the axle)",
    **{
        name: f"its recipe on today's default grid is bc_offroad_nav_v2_detector; {what}"
        for name, what in {
            "ppo_offroad_nav_v2_clone": "it was cloned on the oracle grid",
            "ppo_offroad_nav_v2_clone_160k": "it was cloned on the oracle grid",
            "ppo_offroad_nav_v2_detector_clone": "it was cloned on an older detector grid (paper N's "
            "fusion history, LUX 2.0 m ahead of the axle)",
            "ppo_offroad_nav_v2_detector_clone_tight": "it was cloned with the LUX 2.0 m ahead of the axle",
            "ppo_offroad_nav_v2_structure_clone": "it was cloned on offroad_nav_v2_structure's grid",
            "ppo_offroad_nav_v2_structure_clone_tight": "it was cloned on offroad_nav_v2_structure's grid",
        }.items()
    },
}


def shipped_name(name: str, field: str = "model_path") -> str:
    """The current name of a shipped policy named ``name``: itself, or the new name of a
    renamed one (with a FutureWarning).

    Raises:
        ConfigError: ``name`` was retired (named after ``field``; the message says what instead).
    """
    if name in RETIRED:
        raise ConfigError(
            field,
            f"the shipped policy {name!r} was retired ({RETIRED[name]}; its record: "
            f"docs/notebook/training.md); shipped: {baseline_names()}",
        )
    if name in RENAMED:
        warnings.warn(
            f"the shipped policy {name!r} is now {RENAMED[name]!r}; the old name goes in the next release",
            FutureWarning,
            stacklevel=3,
        )
        return RENAMED[name]
    return name


def baseline_names() -> list[str]:
    """Names of the shipped baselines, sorted."""
    return sorted(p.stem for p in BASELINE_DIR.glob("*.zip"))


def baseline_record(name: str) -> dict[str, Any]:
    """The ``NAME.json`` record of a shipped baseline (command, seed, steps, wall time, results).

    Raises:
        ConfigError: no baseline of that name (field ``model_path``).
    """
    path = BASELINE_DIR / f"{shipped_name(name)}.json"
    if not path.exists():
        raise ConfigError("model_path", f"no shipped baseline {name!r}; shipped: {baseline_names()}")
    return json.loads(path.read_text(encoding="utf-8"))


def resolve_model(model: str, field: str = "model_path") -> str:
    """``model`` if a file exists there (with or without ``.zip``), else the shipped baseline of
    that name.

    Raises:
        ConfigError: neither a saved model nor a shipped baseline (named after ``field``).
    """
    if Path(model).exists() or Path(f"{model}.zip").exists():
        return model
    shipped = BASELINE_DIR / f"{shipped_name(model, field)}.zip"
    if shipped.exists():
        return str(shipped)
    raise ConfigError(
        field, f"no saved model at {model} and no shipped baseline of that name ({baseline_names()})"
    )


def recorded_env(model: str) -> tuple[str, tuple[str, ...]] | None:
    """The env a model was fitted on and the ``--set`` assignments it was fitted with, from its
    record: a shipped baseline's ``NAME.json`` (``env``, ``set``; also when the model is named by
    its file under :data:`BASELINE_DIR`, before the record inside it: ``set`` leaves out the
    training grid of a policy judged on the detector grid); the record ``negobs train``
    saved inside the zip (:data:`FITTED_ON`: the env as the command named it and its ``--set``,
    so a model moved out of its run folder keeps it); or, for a model saved before that record
    existed, the ``train.json`` of the ``negobs train`` folder the model file lies in
    (``model.zip``, ``warm_start.zip``, ``checkpoints/model_N.zip``; a ``--set`` run's
    ``OUT/scenario.toml``, found beside it). None when there is no record, so evaluating on
    another grid than the one trained on is never silent.

    Raises:
        ConfigError: ``model`` names a retired shipped policy (:data:`RETIRED`).
    """
    path = Path(model) if Path(model).exists() else Path(f"{model}.zip")
    if not path.exists():
        if model in RETIRED:
            shipped_name(model)  # raises, naming what to use instead
        if not (BASELINE_DIR / f"{RENAMED.get(model, model)}.zip").exists():
            return None
        return _baseline_env(model)
    if path.suffix == ".zip" and path.resolve().parent == BASELINE_DIR.resolve():
        return _baseline_env(path.stem)  # a shipped baseline named by its file: its NAME.json
    inside = _zip_record(path)
    if inside is not None:
        return inside
    for folder in (path.parent, path.parent.parent):
        run = folder / "train.json"
        if run.is_file():
            return recorded_env_in(
                str(json.loads(run.read_text(encoding="utf-8"))["config"]["env"]), folder
            ), ()
    return None


def _baseline_env(name: str) -> tuple[str, tuple[str, ...]]:
    """A shipped baseline's env and --set, from its NAME.json."""
    record = baseline_record(name)
    return str(record["env"]), tuple(record.get("set", ()))


def fitted_on_record(env: str, overrides: Sequence[str] = ()) -> dict[str, Any]:
    """The :data:`FITTED_ON` record of a model fitted on ``env`` with ``--set`` ``overrides``; a
    scenario file is recorded by its absolute path, so the model finds it from any directory."""
    env = str(env)
    if env.endswith(".toml") and Path(env).is_file():
        env = str(Path(env).resolve())
    return {"env": env, "set": [str(s) for s in overrides]}


def _zip_record(path: Path) -> tuple[str, tuple[str, ...]] | None:
    """The :data:`FITTED_ON` record in a stable-baselines3 zip's ``data`` member; None when the
    file is no such zip, was saved without one or holds a malformed one (SB3 itself reports a
    bad file on loading)."""
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
    except (zipfile.BadZipFile, KeyError, OSError, ValueError):
        return None
    record = data.get(FITTED_ON) if isinstance(data, dict) else None
    if not isinstance(record, dict) or not isinstance(record.get("env"), str):
        return None
    settings = record.get("set", [])
    if not isinstance(settings, list) or not all(isinstance(s, str) for s in settings):
        return None
    return record["env"], tuple(settings)
