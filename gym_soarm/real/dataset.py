"""Reading a recorded LeRobot SO-101 dataset: what a replay and a fit compare with.

:func:`read_replay_dataset` reads a LeRobotDataset v3.0 folder's ``action`` and
``observation.state`` with pyarrow alone (no LeRobot, no torch), the units its joints are
in, and, from a gym_soarm recording, the settings it was made with
(``meta/gym_soarm.json``) and each episode's task and reset seed
(``meta/variation.jsonl``). :mod:`gym_soarm.real.replay` explains what the dataset must
hold and how the units are told.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gym_soarm.envs.settings import EnvSettings
from gym_soarm.real.units import FEATURE_NAMES, RADIANS
from gym_soarm.record.attempt import VARIATION_PATH
from gym_soarm.record.record import SETTINGS_PATH, robot_type_for

KEYS: tuple[str, ...] = ("action", "observation.state")
"""The dataset features a replay reads."""


def _refuse(root: object, problem: str, fix: str) -> ValueError:
    return ValueError(f"dataset {root}: {problem}. {fix}")


def _names(spec: Mapping[str, Any]) -> list[str] | None:
    names = spec.get("names")
    if isinstance(names, Mapping) and len(names) == 1:  # {"motors": [...]} in older files
        names = next(iter(names.values()))
    return list(names) if isinstance(names, (list, tuple)) else None


@dataclass(frozen=True)
class ReplayDataset:
    """The parts of a dataset that a replay reads.

    Attributes:
        root: the dataset folder.
        fps: its frame rate.
        robot_type: ``info.json``'s ``robot_type`` (None when absent).
        units: the units of its joints, as detected (see the module docstring).
        episodes: episode index -> (actions, states), each (frames, 6) float64.
    """

    root: Path
    fps: int
    robot_type: str | None
    units: str
    episodes: dict[int, tuple[np.ndarray, np.ndarray]]
    settings: Mapping[str, Any] | None = None
    """``meta/gym_soarm.json`` of a gym_soarm recording (units, offset, calibration)."""
    recorded: EnvSettings | None = None
    """The environment settings a gym_soarm recording was made with (``"env"`` of
    ``meta/gym_soarm.json``); None for other datasets and older recordings."""
    origins: Mapping[int, tuple[str, int]] | None = None
    """Episode index -> (task, reset seed), from a gym_soarm recording."""


def read_replay_dataset(
    root: str | os.PathLike[str], episodes: Sequence[int] | None = None
) -> ReplayDataset:
    """Read the ``action`` and ``observation.state`` of a LeRobotDataset v3.0 folder.

    Args:
        root: the dataset folder (holding ``meta/info.json`` and ``data/``).
        episodes: the episode indices to read; None for all.

    Raises:
        ValueError: the folder is not a v3.0 dataset, lacks ``action`` or
            ``observation.state``, names their values otherwise than the SO-101
            follower, or has no episode of an asked index.
        ImportError: pyarrow is missing (``pip install "gym-soarm[dataset]"``).
    """
    try:
        import pyarrow  # noqa: F401
    except ImportError as exc:
        raise ImportError(
            "Reading LeRobot datasets needs pyarrow: pip install 'gym-soarm[dataset]'"
        ) from exc
    folder = Path(root)
    info = _read_info(folder, root)
    fps = info.get("fps")
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not fps > 0:
        raise _refuse(root, f"fps is {fps!r}", "info.json must give a positive frame rate.")
    robot_type = info.get("robot_type")
    settings = _read_json(folder / SETTINGS_PATH, root)
    units = RADIANS if robot_type == robot_type_for(RADIANS) else "lerobot"
    if settings is not None:
        units = settings.get("units", units)
    origins = _read_origins(folder / VARIATION_PATH, root)
    chosen = _read_episodes(folder, root, episodes)
    recorded = None
    if settings is not None and "env" in settings:
        try:
            recorded = EnvSettings.from_dict(settings["env"])
        except (TypeError, ValueError) as exc:
            problem = f"{SETTINGS_PATH} holds bad settings ({exc})"
            raise _refuse(root, problem, "Check the file.") from exc
    return ReplayDataset(
        folder,
        fps,
        robot_type,
        units,
        chosen,
        settings=settings,
        origins=origins,
        recorded=recorded,
    )


def _read_info(folder: Path, root: str | os.PathLike[str]) -> dict[str, Any]:
    """``meta/info.json`` of a v3.0 dataset whose ``action`` and ``observation.state``
    are the SO-101 follower's (else ValueError naming the fix)."""
    if not folder.is_dir():
        raise _refuse(root, "no such folder", "Pass the folder that holds meta/info.json.")
    info_path = folder / "meta" / "info.json"
    if not info_path.is_file():
        raise _refuse(
            root,
            "no meta/info.json, so not a LeRobot dataset",
            "Pass the dataset's root folder (the one holding meta/ and data/).",
        )
    try:
        info = json.loads(info_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _refuse(root, f"meta/info.json cannot be read ({exc})", "Check the file.") from exc
    version = info.get("codebase_version")
    if version != "v3.0":
        raise _refuse(
            root,
            f"codebase_version is {version!r}, not 'v3.0'",
            "Convert it with LeRobot's v2.1-to-v3.0 script first.",
        )
    features = info.get("features", {})
    for key in KEYS:
        if key not in features:
            raise _refuse(
                root,
                f"no {key!r} feature (it has {', '.join(sorted(features)) or 'none'})",
                "A replay needs the recorded joint targets ('action') and joint positions "
                "('observation.state') of an SO-101 follower.",
            )
        names = _names(features[key])
        if names != list(FEATURE_NAMES):
            raise _refuse(
                root,
                f"{key!r} has the values {names!r}; expected the SO-101 follower's "
                f"{list(FEATURE_NAMES)!r}",
                "Replay takes absolute joint positions (lerobot-record, or the recorder's "
                "control_mode='joint_pos').",
            )
    return info


def _read_episodes(
    folder: Path, root: str | os.PathLike[str], episodes: Sequence[int] | None
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Episode index -> (actions, states) of the asked episodes (None: all), in frame
    order, from the dataset's parquet files."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    files = sorted((folder / "data").glob("chunk-*/file-*.parquet"))
    if not files:
        raise _refuse(root, "no data/chunk-*/file-*.parquet", "The dataset has no frames.")
    columns = ["index", "episode_index", *KEYS]
    table = pa.concat_tables(pq.read_table(f, columns=columns) for f in files)
    order = np.argsort(table.column("index").to_numpy(), kind="stable")
    episode_of = table.column("episode_index").to_numpy()[order]
    arrays = {}
    for key in KEYS:
        column = table.column(key).combine_chunks()
        values = column.flatten().to_numpy(zero_copy_only=False)
        arrays[key] = values.reshape(len(column), -1)[order].astype(np.float64)
    present = sorted(int(e) for e in np.unique(episode_of))
    wanted = present if episodes is None else list(episodes)
    for index in wanted:
        if index not in present:
            raise _refuse(
                root,
                f"no episode {index!r}; it has {len(present)} episode(s), indices "
                f"{present[0]} to {present[-1]}",
                "Pass one of those, or no episode to replay them all.",
            )
    return {
        index: (
            arrays["action"][episode_of == index],
            arrays["observation.state"][episode_of == index],
        )
        for index in wanted
    }


def _read_json(path: Path, root: str | os.PathLike[str]) -> dict[str, Any] | None:
    if not path.is_file():
        return None
    try:
        content = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _refuse(root, f"{path.name} cannot be read ({exc})", "Check the file.") from exc
    if not isinstance(content, dict):
        raise _refuse(root, f"{path.name} is not a JSON object", "Check the file.")
    return content


def _read_origins(path: Path, root: str | os.PathLike[str]) -> dict[int, tuple[str, int]] | None:
    if not path.is_file():
        return None
    origins: dict[int, tuple[str, int]] = {}
    for text in path.read_text(encoding="utf-8").splitlines():
        try:
            line = json.loads(text)
            origins[int(line["episode_index"])] = (str(line["task"]), int(line["seed"]))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError):
            continue  # a line without an episode's origin (older recordings): not used
    return origins or None
