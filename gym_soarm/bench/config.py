"""What the benchmark measures: a configuration (:class:`BenchConfig`, named like ``state``
or ``front_wrist_640x480_high``) and the benchmark's defaults."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from typing import Any

from gym_soarm.tasks import DEFAULT_TASK

DEFAULT_CONFIGS: tuple[str, ...] = (
    "state",
    "state_30hz",
    "front_only_640x480",
    "front_wrist_640x480",
    "all_640x480",
    "front_wrist_224x224",
    "front_wrist_640x480_high",
)
DEFAULT_SECONDS = 3.0
DEFAULT_REPEATS = 3
DEFAULT_JSON = "bench_results.json"
"""Where the results go without --json: a name the repository ignores, so the checkout stays clean."""
DEFAULT_CONTROL_MODE = "joint_pos"
ACTION_SEED = 0
N_ACTIONS = 1024  # random actions drawn up front and cycled, so drawing costs nothing
SLICES_PER_REPEAT = 4  # each repeat alternates this many slices of env and ceiling
STATE_RESETS = 50
PIXEL_RESETS = 5
DEFAULT_IMAGE_SIZE = (96, 128)  # (height, width) of --vector-obs and --recording-cameras

_STATE_RATE_PATTERN = re.compile(r"^state_(\d+)hz$")
_CONFIG_PATTERN = re.compile(r"^(front_only|front_wrist|all)_(\d+)x(\d+)(?:_(fast|high))?$")


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """One measured configuration, named like ``state`` or ``front_wrist_640x480_high``."""

    name: str
    obs_type: str
    camera_config: str | None
    width: int
    height: int
    render_quality: str
    task: str = DEFAULT_TASK
    control_mode: str = DEFAULT_CONTROL_MODE
    env: tuple[tuple[str, Any], ...] = ()
    """Further ``gym.make`` keywords (``("dynamics", PATH)``, ...), as sorted pairs."""

    @classmethod
    def parse(
        cls,
        name: str,
        task: str = DEFAULT_TASK,
        control_mode: str = DEFAULT_CONTROL_MODE,
        env: Mapping[str, Any] | None = None,
    ) -> BenchConfig:
        """The configuration called ``name``, on ``task`` (a registered task), with the
        further ``gym.make`` keywords ``env`` (not those the name sets).

        Raises:
            ValueError: ``name`` is not ``state`` or ``{cameras}_{W}x{H}[_fast|_high]``,
                ``task`` is not registered, ``control_mode`` is unknown, or ``env`` has
                a bad or a reserved keyword.
        """
        config = cls._parse(name, task, control_mode)
        named = dict(config.env)  # what the name sets (state_30hz: control_hz)
        env = {k: v for k, v in dict(env or {}).items() if k not in named or named[k] != v}
        if not env:
            return config
        reserved = sorted(set(env) & {"task", "control_mode", *config.env_kwargs()})
        if reserved:
            raise ValueError(
                f"env keywords {reserved} are set by the configuration name, --task or "
                "--control-mode; leave them out of env."
            )
        from gym_soarm.envs.settings import EnvSettings

        EnvSettings.from_kwargs(task=config.task, **config.env_kwargs(), **env)  # checks
        return dataclasses.replace(config, env=tuple(sorted({**named, **env}.items())))

    @classmethod
    def _parse(cls, name: str, task: str, control_mode: str) -> BenchConfig:
        from gym_soarm.envs.control import CONTROL_MODES
        from gym_soarm.tasks import get_task
        from gym_soarm.validation import check_choice

        task = get_task(task).name
        check_choice("control_mode", control_mode, CONTROL_MODES)
        if name in ("state", "state_fast"):
            return cls(
                "state", "environment_state_agent_pos", None, 0, 0, "fast", task, control_mode
            )
        rate = _STATE_RATE_PATTERN.match(name)
        if rate is not None:  # state at another control rate: state_30hz
            from gym_soarm.sim.timing import check_control_hz

            hz = check_control_hz("the rate of " + name, int(rate.group(1)))
            return cls(
                name,
                "environment_state_agent_pos",
                None,
                0,
                0,
                "fast",
                task,
                control_mode,
                env=(("control_hz", hz),),
            )
        match = _CONFIG_PATTERN.match(name)
        if match is None:
            raise ValueError(
                f"unknown benchmark configuration {name!r}; expected 'state', 'state_{{HZ}}hz' or "
                "'{front_only|front_wrist|all}_{W}x{H}' with an optional '_fast' or '_high' "
                f"suffix, e.g. {', '.join(DEFAULT_CONFIGS)}."
            )
        cameras, width, height, quality = match.groups()
        return cls(
            name,
            "pixels_agent_pos",
            cameras,
            int(width),
            int(height),
            quality or "fast",
            task,
            control_mode,
        )

    @classmethod
    def from_job(cls, job: Mapping[str, Any]) -> BenchConfig:
        """The configuration a worker's job names (:meth:`job`)."""
        return cls.parse(job["config"], job["task"], job["control_mode"], job["env"])

    def job(self) -> dict[str, Any]:
        """The configuration as a worker's job names it (JSON)."""
        return {
            "config": self.name,
            "task": self.task,
            "control_mode": self.control_mode,
            "env": dict(self.env),
        }

    @property
    def env_id(self) -> str:
        from gym_soarm.tasks import get_task

        return get_task(self.task).env_id

    @property
    def renders(self) -> bool:
        return self.camera_config is not None

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``gym.make`` for this configuration."""
        kwargs: dict[str, Any] = {
            "obs_type": self.obs_type,
            "render_quality": self.render_quality,
            "control_mode": self.control_mode,
        }
        if self.renders:
            kwargs.update(
                camera_config=self.camera_config,
                observation_width=self.width,
                observation_height=self.height,
            )
        kwargs.update(self.env)
        return kwargs
