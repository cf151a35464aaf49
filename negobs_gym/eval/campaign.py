"""Campaign runner: episodes in order, in local processes or on Ray, resumable, byte-identical output.

A campaign is a list of :class:`Episode` tasks (a unique sortable ``key`` and the picklable
arguments of one episode) and a module-level function ``run(episode) -> {table: [row, ...]}`` that
returns CSV rows already formatted as strings (see :func:`format_row`). The runner

- runs the episodes serially, in ``workers`` spawned processes (``concurrent.futures``), or as Ray
  tasks (``ray`` is the optional extra ``negobs_gym[ray]``);
- writes each finished episode's rows to ``out/parts/<key>.json`` atomically (temp file +
  ``os.replace``), from the driver process only, so a killed campaign leaves whole parts or none;
- with ``resume=True`` skips episodes whose part exists (each part records the arguments it ran
  with; a part run with other arguments is an error, never a row mixed in), otherwise starts from
  an empty parts dir;
- assembles ``out/<table>.csv`` from the parts sorted by key, so the bytes depend on the seeds only,
  never on the backend, the worker count or the order in which episodes finished.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import multiprocessing
import os
import shutil
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from negobs_gym.core.files import write_text_atomic
from negobs_gym.errors import ConfigError, MissingDependencyError, require

log = logging.getLogger(__name__)

PARTS_DIR = "parts"
FLOAT_DIGITS = 6  # fixed decimals in every CSV: identical floats give identical text on any backend

Rows = dict[str, list[str]]
EpisodeFn = Callable[["Episode"], Rows]


@dataclass(frozen=True)
class Episode:
    """One unit of work: ``key`` names it (sorting keys gives the CSV row order), ``args`` runs it."""

    key: str
    args: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.key or any(c in self.key for c in "/\\\0") or self.key.startswith("."):
            raise ConfigError("key", f"must be a non-empty file-name-safe string, got {self.key!r}")


def format_value(value: Any) -> str:
    """Deterministic CSV text: floats with :data:`FLOAT_DIGITS` decimals (``nan``/``inf`` spelled out)."""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        text = f"{value:.{FLOAT_DIGITS}f}"
        return "0." + "0" * FLOAT_DIGITS if text == "-0." + "0" * FLOAT_DIGITS else text
    text = str(value)
    if any(c in text for c in ',"\n'):
        raise ConfigError(
            "csv_value",
            f"{text!r} holds a comma, quote or newline (a name written to a results table cannot)",
        )
    return text


def format_row(values: Iterable[Any]) -> str:
    """One CSV line (no newline) of :func:`format_value` texts."""
    return ",".join(format_value(v) for v in values)


@dataclass(frozen=True)
class Backend:
    """Where episodes run: ``workers`` local processes, or Ray when ``ray`` is set.

    ``ray``: None (no Ray), ``"local"`` (start a local Ray instance) or a cluster address
    (``"auto"``, ``"ray://host:10001"``, ...).
    """

    workers: int = 1
    ray: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.workers, int) or self.workers < 1:
            raise ConfigError("workers", f"must be an integer >= 1, got {self.workers!r}")


def _args_record(args: Mapping[str, Any]) -> Any:
    """An episode's arguments as plain JSON (config dataclasses by their repr): what a part ran with."""
    return json.loads(json.dumps(args, sort_keys=True, default=repr))


def _read_part(path: Path, episode: Episode) -> Rows:
    """A finished part's rows, after checking that it ran with ``episode``'s arguments.

    Raises:
        ConfigError: the part ran with other arguments (a resumed campaign whose settings changed,
            e.g. another rig or detector setting, into the same ``--out``). Parts written before
            the arguments were recorded carry none and are taken as they are.
    """
    data = json.loads(path.read_text(encoding="utf-8"))
    if "args" in data:
        want = _args_record(episode.args)
        diff = sorted(k for k in set(data["args"]) | set(want) if data["args"].get(k) != want.get(k))
        require(
            not diff,
            f"{PARTS_DIR}/{path.name}",
            "was run with other settings ("
            + ", ".join(f"{k}: kept {data['args'].get(k)!r}, asked {want.get(k)!r}" for k in diff)
            + "); rerun without resume or into another output folder",
        )
    return {str(k): [str(r) for r in v] for k, v in data["rows"].items()}


def _write_part(parts: Path, episode: Episode, rows: Rows) -> None:
    record = {"key": episode.key, "args": _args_record(episode.args), "rows": rows}
    write_text_atomic(parts / f"{episode.key}.json", json.dumps(record, sort_keys=True))


def _serial(fn: EpisodeFn, todo: Sequence[Episode]) -> Iterator[tuple[Episode, Rows]]:
    for episode in todo:
        yield episode, fn(episode)


def _processes(fn: EpisodeFn, todo: Sequence[Episode], workers: int) -> Iterator[tuple[Episode, Rows]]:
    # spawn: no inherited PyBullet/Embree state, same start method on every OS
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
        pending = {pool.submit(fn, ep): ep for ep in todo}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                yield pending.pop(future), future.result()


def import_ray() -> Any:
    """The ``ray`` module, or :class:`MissingDependencyError` naming the extra that installs it."""
    try:
        import ray
    except ImportError as error:
        raise MissingDependencyError("negobs_gym[ray]", "running campaigns on Ray (--ray)") from error
    return ray


@contextlib.contextmanager
def ray_session(address: str = "", cpus: int | None = None) -> Iterator[Any]:
    """Ray, started for the ``with`` block unless this process already runs it: a local instance
    for ``address`` "" or "local" (with at least ``cpus`` CPUs, so that many one-CPU tasks or
    actors all start), else the cluster at ``address``; shut down at the end if started here.

    Raises:
        MissingDependencyError: ``ray`` is not installed (``negobs_gym[ray]``).
    """
    ray = import_ray()
    started_here = not ray.is_initialized()
    if started_here:
        if address and address != "local":
            ray.init(address=address, log_to_driver=False)
        else:
            # a source checkout (not installed) must be importable by the local workers too
            package_root = str(Path(__file__).resolve().parents[2])
            path = os.pathsep.join(p for p in (package_root, os.environ.get("PYTHONPATH", "")) if p)
            ray.init(
                num_cpus=max(os.cpu_count() or 1, cpus or 1),
                include_dashboard=False,
                log_to_driver=False,
                runtime_env={"env_vars": {"PYTHONPATH": path}},
            )
    try:
        yield ray
    finally:
        if started_here:
            ray.shutdown()


def _ray(fn: EpisodeFn, todo: Sequence[Episode], address: str) -> Iterator[tuple[Episode, Rows]]:
    with ray_session(address) as ray:
        remote = ray.remote(fn)
        pending = {remote.remote(ep): ep for ep in todo}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                yield pending.pop(ref), ray.get(ref)


def run_episodes(
    fn: EpisodeFn,
    episodes: Sequence[Episode],
    out_dir: str | Path,
    *,
    backend: Backend | None = None,
    resume: bool = False,
    progress: bool = True,
    description: str = "episodes",
) -> dict[str, Rows]:
    """Run every episode not finished yet; returns all finished episodes' rows by key.

    Raises :class:`ConfigError` on duplicate keys. Without ``resume`` an existing parts dir is
    cleared first (a fresh campaign); with it, finished parts are kept and their episodes skipped.
    """
    from tqdm import tqdm

    backend = backend or Backend()
    keys = [ep.key for ep in episodes]
    if len(set(keys)) != len(keys):
        raise ConfigError("episodes", "episode keys must be unique")
    parts = Path(out_dir) / PARTS_DIR
    if parts.exists() and not resume:
        shutil.rmtree(parts)
    parts.mkdir(parents=True, exist_ok=True)
    for stale in parts.glob(".*.tmp*"):  # a temp file of a killed run: never a finished part
        stale.unlink()
    finished = {p.stem: p for p in parts.glob("*.json") if p.stem in set(keys)}
    todo = [ep for ep in episodes if ep.key not in finished]
    if resume:
        log.info("resume: %d of %d episodes already finished in %s", len(finished), len(keys), parts)
    results = {ep.key: _read_part(finished[ep.key], ep) for ep in episodes if ep.key in finished}
    if todo:
        if backend.ray is not None:
            stream = _ray(fn, todo, backend.ray)
        elif backend.workers > 1 and len(todo) > 1:
            stream = _processes(fn, todo, min(backend.workers, len(todo)))
        else:
            stream = _serial(fn, todo)
        with tqdm(total=len(keys), initial=len(finished), desc=description, disable=not progress) as bar:
            for episode, rows in stream:
                _write_part(parts, episode, rows)
                results[episode.key] = rows
                bar.update(1)
    return results


def assemble_csv(
    results: Mapping[str, Rows], table: str, header: Sequence[str], out_path: str | Path
) -> Path:
    """Write ``table``'s rows of every episode, episodes sorted by key, under ``header``, atomically.

    Every episode function returns each of its tables, empty where the episode has no row in it,
    so a part without ``table`` is one kept by ``resume`` from a version that had no such table.

    Raises:
        ConfigError: a row whose field count is not the header's (a part kept by ``resume`` from a
            campaign whose table had other columns, e.g. written by another version), or a part
            without the table.
    """
    lines = [",".join(header)]
    for key in sorted(results):
        require(
            table in results[key],
            f"{PARTS_DIR}/{key}.json",
            f"has no {table!r} table: a kept part from a campaign without it; rerun without resume",
        )
        for row in results[key][table]:
            fields = row.count(",") + 1
            require(
                fields == len(header),
                f"{table}[{key}]",
                f"has {fields} fields, the table's header {len(header)}: a kept part from a campaign "
                "with other columns; rerun without resume",
            )
            lines.append(row)
    return write_text_atomic(out_path, "\n".join(lines) + "\n")


@dataclass(frozen=True)
class RunOptions:
    """How a campaign runs: where (``backend``), whether it resumes, whether it shows a progress bar."""

    backend: Backend = field(default_factory=Backend)
    resume: bool = False
    progress: bool = True


def run_campaign(
    fn: EpisodeFn,
    episodes: Sequence[Episode],
    out_dir: str | Path,
    tables: Mapping[str, Sequence[str]],
    options: RunOptions | None = None,
    description: str = "episodes",
) -> dict[str, Path]:
    """:func:`run_episodes` then :func:`assemble_csv` of each table (name -> header) to ``out/<name>.csv``."""
    opts = options or RunOptions()
    results = run_episodes(
        fn,
        episodes,
        out_dir,
        backend=opts.backend,
        resume=opts.resume,
        progress=opts.progress,
        description=description,
    )
    return {
        name: assemble_csv(results, name, header, Path(out_dir) / f"{name}.csv")
        for name, header in tables.items()
    }


def scene_assignments(fields: Mapping[str, Any], paths: Mapping[str, str]) -> list[str]:
    """``KEY.PATH=VALUE`` assignments (the ``--set`` paths) of the options named in ``paths``
    that ``fields`` sets (None: not set), in ``paths``' order; other keys are ignored. The
    campaigns' options that set a field of their scenes (``negobs eval braking --rig``) and the
    config fields they once copied go through it."""
    return [
        f"{path}={json.dumps(fields[name])}" for name, path in paths.items() if fields.get(name) is not None
    ]


def read_csv(path: str | Path) -> list[dict[str, str]]:
    """Rows of a campaign CSV as dicts of text (the writer never quotes, see :func:`format_value`)."""
    lines = Path(path).read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    return [dict(zip(header, line.split(","), strict=True)) for line in lines[1:] if line]
