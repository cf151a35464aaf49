"""Trained policies shipped with the package (``negobs_gym/policies/trained/NAME.zip``).

Each ``NAME.zip`` is a stable-baselines3 model saved by ``negobs train``; ``NAME.json`` beside it
records the exact command, seed, steps, wall time and the evaluation that was measured on it
(docs/training.md). ``negobs eval policy NAME`` and :func:`resolve_model` accept a baseline's
name wherever a model path is asked for.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from negobs_gym.errors import ConfigError

__all__ = ["BASELINE_DIR", "baseline_names", "baseline_record", "recorded_env", "resolve_model"]

BASELINE_DIR = Path(__file__).with_name("trained")


def baseline_names() -> list[str]:
    """Names of the shipped baselines, sorted."""
    return sorted(p.stem for p in BASELINE_DIR.glob("*.zip"))


def baseline_record(name: str) -> dict[str, Any]:
    """The ``NAME.json`` record of a shipped baseline (command, seed, steps, wall time, results).

    Raises:
        ConfigError: no baseline of that name (field ``model_path``).
    """
    path = BASELINE_DIR / f"{name}.json"
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
    shipped = BASELINE_DIR / f"{model}.zip"
    if shipped.exists():
        return str(shipped)
    raise ConfigError(
        field, f"no saved model at {model} and no shipped baseline of that name ({baseline_names()})"
    )


def recorded_env(model: str) -> tuple[str, tuple[str, ...]] | None:
    """The env a model was fitted on and the ``--set`` assignments it was fitted with, from its
    record: a shipped baseline's ``NAME.json`` (``env``, ``set``), or the ``train.json`` of the
    ``negobs train`` folder the model file lies in (``model.zip``, ``warm_start.zip``,
    ``checkpoints/model_N.zip``; a ``--set`` run's ``OUT/scenario.toml``, found beside it). None when
    there is no record, so evaluating on another grid than the one trained on is never silent.
    """
    path = Path(model) if Path(model).exists() else Path(f"{model}.zip")
    if not path.exists():
        if not (BASELINE_DIR / f"{model}.zip").exists():
            return None
        record = baseline_record(model)
        return str(record["env"]), tuple(record.get("set", ()))
    for folder in (path.parent, path.parent.parent):
        run = folder / "train.json"
        if run.is_file():
            from negobs_gym.scenarios.overrides import recorded_env_in

            return recorded_env_in(
                str(json.loads(run.read_text(encoding="utf-8"))["config"]["env"]), folder
            ), ()
    return None
