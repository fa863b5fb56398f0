"""One frozen settings object for every ``gym.make`` keyword of gym_soarm.

:class:`EnvSettings` holds the keywords of :class:`gym_soarm.envs.env.SoArmEnv` as fields, each
with its type, default, a one-line doc and its check; an instance checks (and normalises)
all of them once, when it is made. ``SoArmEnv`` builds one from its keywords
(``env.unwrapped.settings``) and also takes one whole (``gym.make(id, settings=s)``); the
programs generate their command-line flags from the fields
(:func:`gym_soarm.cli.settings.add_settings_arguments`) and recordings store them
(:meth:`EnvSettings.to_json`). A new keyword is one field here (with its description in
the class docstring) and its use where the environment is built (``world.py``) or reads it.
:func:`resolve_settings` is how ``SoArmEnv`` turns its arguments into settings, and
:func:`setting_property` makes each field an attribute of the environment.

>>> from gym_soarm.envs.settings import EnvSettings
>>> s = EnvSettings(task="lift", obs_type="state", servo_model="sts3215")
>>> s.task, s.camera_config
('LiftCube-v0', ('front_camera', 'wrist_camera'))
>>> EnvSettings.from_json(s.to_json()) == s
True

Files named by ``calibration`` and ``dynamics`` are read when an environment is built,
not here: a settings object can travel to a machine that holds them elsewhere.
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from gym_soarm import constants
from gym_soarm.envs.control import CONTROL_MODES
from gym_soarm.real.unit_maps import LEROBOT, UNITS, check_wrist_roll_offset
from gym_soarm.render.backend import RENDER_QUALITIES
from gym_soarm.sim.randomization import LEVELS, SERVO_MODELS
from gym_soarm.sim.timing import DEFAULT_CONTROL_HZ, check_control_hz
from gym_soarm.tasks import DEFAULT_TASK, get_task
from gym_soarm.tasks.distractors import MAX_DISTRACTORS
from gym_soarm.validation import (
    ArgumentTypeError,
    check_bool,
    check_choice,
    check_image_size,
    check_int,
    check_subset,
    resolve_camera_config,
)

OBS_TYPES = ("pixels", "pixels_agent_pos", "environment_state_agent_pos", "state")
STATE_OBS_TYPES = ("environment_state_agent_pos", "state")
"""The observation types that render nothing."""
REWARD_TYPES = ("dense", "sparse")
PLACEMENTS = ("grid", "uniform")
IMAGE_MODALITIES = ("rgb", "depth", "segmentation")
RENDER_MODES = ("human", "rgb_array")
SETTINGS_FORMAT = "gym_soarm.env_settings/1"
"""The ``format`` of :meth:`EnvSettings.to_dict`'s JSON object."""


_PATHS = {
    "calibration": ("a LeRobot calibration JSON file", "Pass e.g. calibration='follower.json'."),
    "dynamics": (
        "a gym_soarm.dynamics/1 JSON file",
        "Fit one with python -m gym_soarm.sysid.",
    ),
}


def _check_path(name: str, value: Any) -> str | None:
    """A file's path as a str (None stays None); the file itself is read by the env."""
    if value is None:
        return None
    if not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
        what, fix = _PATHS[name]
        raise ArgumentTypeError(
            f"{name} must be the path of {what} (str or os.PathLike) or None; got {value!r} "
            f"({type(value).__name__}). {fix}"
        )
    return os.fspath(value)


def _setting(
    default: Any,
    doc: str,
    check: Callable[[str, Any], Any] | None = None,
    *,
    choices: Sequence[str] | None = None,
    type_text: str | None = None,
    parse: Callable[[str], Any] | None = None,
    metavar: str | None = None,
) -> Any:
    """A field of :class:`EnvSettings`: its default, one-line doc and check.

    ``check(name, value)`` returns the value as stored (normalised) or raises
    ``ValueError``/``TypeError``; ``choices`` are the valid strings of a choice field
    (for command lines and docs), and without a ``check`` the value must be one of them
    (or None, where None is the default); ``parse(text)`` reads a command line's text (default:
    by the default's type: str, int, float or a bool flag); ``metavar`` names its value in
    ``--help``.
    """
    if check is None:
        if choices is None:
            raise TypeError("a setting needs a check or its choices")  # pragma: no cover
        valid, none_ok = choices, default is None

        def check(name: str, value: Any) -> Any:
            return check_choice(name, value, valid, none_ok=none_ok)

    metadata = {
        "doc": doc,
        "check": check,
        "choices": choices,
        "type_text": type_text,
        "parse": parse,
        "metavar": metavar,
    }
    if isinstance(default, (list, dict, set)):
        raise TypeError("settings defaults must be immutable")  # pragma: no cover
    return field(default=default, metadata=metadata)


def _comma_list(text: str) -> tuple[str, ...]:
    """``"a,b"`` -> ``("a", "b")`` (command lines)."""
    return tuple(part.strip() for part in text.split(",") if part.strip())


def _camera_text(text: str) -> str | tuple[str, ...]:
    """A camera config's name as is, camera names (``front_camera,wrist_camera``) as a tuple."""
    return text if text in constants.CAMERA_CONFIGS else _comma_list(text)


def _check_task(name: str, value: Any) -> str:
    return get_task(value).name


@dataclass(frozen=True)
class EnvSettings:
    """Every keyword of ``gym.make`` for a gym_soarm environment, checked once.

    Fields keep the keywords' names, types and defaults (of
    :class:`gym_soarm.envs.env.SoArmEnv`); making an instance checks every field and
    normalises a few: ``task`` becomes the registered name (``"lift"`` ->
    ``"LiftCube-v0"``), ``camera_config`` the tuple of camera names, ``image_modalities``
    a tuple in the fixed order, paths plain strings, numbers plain ``int``/``float``.

    Attributes:
        task: a registered task's name (``"PickAndPlaceCube-v0"``, ``"LiftCube-v0"``, ...;
            see :func:`gym_soarm.tasks.task_names`) or one of its aliases.
        obs_type: one of :data:`OBS_TYPES` (see :mod:`gym_soarm.envs.spaces`).
        camera_config: ``"front_only"``, ``"front_wrist"``, ``"all"`` or camera names.
        observation_height: image height in pixels (16 to 2048).
        observation_width: image width in pixels (16 to 2048).
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        render_camera: camera returned by ``render()`` in ``rgb_array`` mode.
        render_quality: ``"fast"`` (simplified visual meshes; no shadows, reflections or
            multisampling) or ``"high"`` (full-detail meshes, shadows, reflections and
            4x multisampling). The physics is the same for both.
        reward_type: ``"dense"`` (weighted named terms in [0, 1]) or ``"sparse"``.
        units: joint units of actions and ``agent_pos``: ``"radians"``, ``"lerobot"``
            or ``"lerobot_range"``.
        wrist_roll_offset_deg: with LeRobot units, the real arm's wrist_roll reading
            (degrees, -180 to 180) when the model's wrist_roll is at 0 rad; wrist_roll
            values are shifted by it and wrapped to a turn (see :mod:`gym_soarm.real.units`).
        image_modalities: images of each camera in pixel observations: a tuple of
            ``"rgb"``, ``"depth"`` and ``"segmentation"`` (see
            :mod:`gym_soarm.envs.spaces`); only these are rendered.
        visual_randomization: ``"none"``, ``"light"`` or ``"heavy"``: lights, table,
            floor and object colours and the cameras drawn anew at every reset (see
            :mod:`gym_soarm.sim.randomization`); the reset's ``info["variation"]`` says
            what was drawn.
        physics_randomization: ``"none"``, ``"light"`` or ``"heavy"``: object mass and
            friction, servo gains and joint damping (+-10 % or +-30 %), and with
            ``"heavy"`` a control delay of 0 or 1 steps, drawn at every reset.
        servo_model: ``"ideal"`` (the servo targets are the actions) or ``"sts3215"``
            (the follower's Feetech STS3215: speed-limited, quantised targets with
            backlash and its stall torque as force range; see
            :class:`gym_soarm.sim.randomization.Sts3215Servo`).
        object_placement: ``"grid"`` or ``"uniform"``: how the task's objects start;
            None: the task's default.
        distractors: extra objects on the table (0 to
            :data:`~gym_soarm.tasks.distractors.MAX_DISTRACTORS`), placed at every reset.
        control_mode: what an action means: ``"joint_pos"`` (absolute servo targets),
            ``"joint_delta"`` (changes of the servo targets), ``"ee_delta"`` (changes of
            the jaws' pose) or ``"ee_pose"`` (the jaws' pose); see
            :mod:`gym_soarm.envs.control`. The ee modes add ``ik_error_m`` and
            ``ik_error_rad`` to ``info``.
        calibration: with LeRobot units, the path of a real SO-101 follower's LeRobot
            calibration JSON: actions, ``agent_pos`` and their bounds are then that arm's
            values, as LeRobot's motor bus normalises them (see
            :mod:`gym_soarm.real.calibration`). None: the fixed maps of :mod:`gym_soarm.real.units`.
        dynamics: the path of a ``gym_soarm.dynamics/1`` JSON file (fitted to a real arm
            by ``python -m gym_soarm.sysid``): its servo gains, joint damping, armature,
            friction loss and control delay replace the model's on this environment's
            own model copy; with ``physics_randomization`` the draws centre on them (see
            :mod:`gym_soarm.real.dynamics`). None: the model's own.
        normalize_actions: ``True``: actions are ``Box(-1, 1, (6,), float32)``, mapped
            linearly onto the control mode's own Box (-1 to its low bound, +1 to its
            high bound), for every control mode; the RL recipes use it.
        control_hz: control steps (and video and dataset frames) a second: 50, or 30 as
            LeRobot records; one that whole physics steps fill (see
            :mod:`gym_soarm.sim.timing`).

    Raises:
        ValueError: a value that is not valid; the message names the keyword, what was
            expected, what came and how to fix it.
        TypeError: a value of the wrong type (also a ``ValueError``; see
            :class:`gym_soarm.validation.ArgumentTypeError`).
    """

    task: str = _setting(
        DEFAULT_TASK,
        "a registered task's name or alias (see gym_soarm.tasks.task_names())",
        _check_task,
        metavar="TASK",
    )
    obs_type: str = _setting(
        "pixels_agent_pos",
        "what an observation holds: images, joint positions, task state or one flat vector",
        choices=OBS_TYPES,
    )
    camera_config: str | Sequence[str] = _setting(
        constants.DEFAULT_CAMERA_CONFIG,
        "the cameras of pixel observations: front_only, front_wrist, all or camera names",
        lambda name, value: resolve_camera_config(value),
        type_text="str | tuple[str, ...]",
        parse=_camera_text,
        metavar="CAMERAS",
    )
    observation_height: int = _setting(
        480, "image height in pixels (16 to 2048)", check_image_size, metavar="PIXELS"
    )
    observation_width: int = _setting(
        640, "image width in pixels (16 to 2048)", check_image_size, metavar="PIXELS"
    )
    render_mode: str | None = _setting(
        None,
        "what render() does: None, rgb_array (returns an image) or human (a window)",
        choices=RENDER_MODES,
    )
    render_camera: str = _setting(
        constants.DEFAULT_RENDER_CAMERA,
        "the camera that render() shows in rgb_array mode",
        choices=constants.CAMERA_NAMES,
    )
    render_quality: str = _setting(
        "fast",
        "fast (simplified meshes, no shadows) or high (full meshes, shadows, 4x MSAA)",
        choices=RENDER_QUALITIES,
    )
    reward_type: str = _setting(
        "dense",
        "dense (the task's weighted named terms in [0, 1]) or sparse (1 on success)",
        choices=REWARD_TYPES,
    )
    units: str = _setting(
        "radians",
        "joint units of actions and agent_pos: radians, lerobot (degrees) or lerobot_range",
        choices=UNITS,
    )
    wrist_roll_offset_deg: float = _setting(
        0.0,
        "with LeRobot units: the real arm's wrist_roll reading (deg) at the model's 0 rad",
        # Type and range here; whether the units take an offset, in __post_init__.
        lambda name, value: check_wrist_roll_offset(LEROBOT, value),
        metavar="DEG",
    )
    image_modalities: Sequence[str] = _setting(
        ("rgb",),
        "images of each camera: a tuple of rgb, depth and segmentation",
        lambda name, value: check_subset(name, value, IMAGE_MODALITIES),
        choices=IMAGE_MODALITIES,
        type_text="tuple[str, ...]",
        parse=_comma_list,
        metavar="MODALITIES",
    )
    visual_randomization: str = _setting(
        "none",
        "lights, colours and cameras drawn at every reset: none, light or heavy",
        choices=LEVELS,
    )
    physics_randomization: str = _setting(
        "none",
        "masses, friction, servo gains and damping drawn at every reset: none, light or heavy",
        choices=LEVELS,
    )
    servo_model: str = _setting(
        "ideal",
        "ideal (targets are the actions) or sts3215 (the follower's speed-limited servos)",
        choices=SERVO_MODELS,
    )
    object_placement: str | None = _setting(
        None,
        "how objects start: grid or uniform (None: the task's default)",
        choices=PLACEMENTS,
    )
    distractors: int = _setting(
        0,
        f"extra objects on the table, 0 to {MAX_DISTRACTORS}",
        lambda name, value: check_int(name, value, 0, MAX_DISTRACTORS),
        metavar="N",
    )
    control_mode: str = _setting(
        "joint_pos",
        "what an action means: joint_pos, joint_delta, ee_delta or ee_pose",
        choices=CONTROL_MODES,
    )
    calibration: str | os.PathLike[str] | None = _setting(  # noqa: RUF009
        None,
        "with LeRobot units: a real follower's LeRobot calibration JSON (None: fixed maps)",
        _check_path,
        type_text="str | None",
        metavar="PATH",
    )
    dynamics: str | os.PathLike[str] | None = _setting(  # noqa: RUF009
        None,
        "a gym_soarm.dynamics/1 JSON (python -m gym_soarm.sysid): servo and joint figures",
        _check_path,
        type_text="str | None",
        metavar="PATH",
    )
    normalize_actions: bool = _setting(
        False,
        "True: actions in Box(-1, 1), mapped linearly onto the control mode's bounds",
        check_bool,
    )
    control_hz: int = _setting(
        DEFAULT_CONTROL_HZ,
        "control steps (and video/dataset frames) a second: 50, or 30 as LeRobot records; "
        "one that whole physics steps fill (see gym_soarm.sim.timing)",
        check_control_hz,
        metavar="HZ",
    )

    def __post_init__(self) -> None:
        for item in dataclasses.fields(self):
            value = item.metadata["check"](item.name, getattr(self, item.name))
            object.__setattr__(self, item.name, value)
        # Checks across fields.
        check_wrist_roll_offset(self.units, self.wrist_roll_offset_deg)
        get_task(self.task).make_task(self.object_placement)  # refuses an unsupported placement

    # --- construction and conversion ---------------------------------------------------
    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The field names, in the order of ``SoArmEnv``'s keywords."""
        return tuple(item.name for item in dataclasses.fields(cls))

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> EnvSettings:
        """Settings from ``gym.make`` keywords; an unknown keyword raises ``TypeError``
        that lists the known ones."""
        unknown = sorted(set(kwargs) - set(cls.names()))
        if unknown:
            close = sorted(
                {
                    m
                    for name in unknown
                    for m in difflib.get_close_matches(name, cls.names(), 3, 0.5)
                }
            )
            hint = f" Did you mean {', '.join(close)}?" if close else ""
            raise ArgumentTypeError(
                f"unknown gym_soarm environment keyword(s) {unknown}.{hint} The keywords are "
                f"{', '.join(cls.names())}; each is described with its values in "
                "docs/keywords.md."
            )
        return cls(**kwargs)

    def to_kwargs(self) -> dict[str, Any]:
        """The settings as ``gym.make`` keywords (every field, normalised)."""
        return {name: getattr(self, name) for name in self.names()}

    def replace(self, **changes: Any) -> EnvSettings:
        """A copy with ``changes`` (checked like :meth:`from_kwargs`)."""
        return type(self).from_kwargs(**{**self.to_kwargs(), **changes})

    def changed(self) -> dict[str, Any]:
        """The fields that differ from the defaults (of a fresh ``EnvSettings()`` with this
        task), as keywords."""
        default = type(self)(task=self.task)
        return {n: v for n, v in self.to_kwargs().items() if v != getattr(default, n)}

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict: ``{"format": ..., <field>: value, ...}`` (tuples as lists)."""
        data: dict[str, Any] = {"format": SETTINGS_FORMAT}
        for name, value in self.to_kwargs().items():
            data[name] = list(value) if isinstance(value, tuple) else value
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> EnvSettings:
        """Settings from :meth:`to_dict`'s dict; fields it lacks keep their defaults.

        Raises:
            ValueError: not a dict of this format, or a bad value.
            TypeError: an unknown field (see :meth:`from_kwargs`).
        """
        if not isinstance(data, Mapping):
            raise ArgumentTypeError(
                f"settings must be a JSON object (dict) of the format {SETTINGS_FORMAT!r}; "
                f"got {type(data).__name__}."
            )
        kwargs = dict(data)
        found = kwargs.pop("format", SETTINGS_FORMAT)
        if found != SETTINGS_FORMAT:
            raise ValueError(
                f"settings format must be {SETTINGS_FORMAT!r}; got {found!r}. Write it with "
                "EnvSettings.to_dict()."
            )
        for name in ("camera_config", "image_modalities"):
            if isinstance(kwargs.get(name), list):
                kwargs[name] = tuple(kwargs[name])
        return cls.from_kwargs(**kwargs)

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text."""
        return json.dumps(self.to_dict(), indent=2)

    @classmethod
    def from_json(cls, text: str) -> EnvSettings:
        """Settings from :meth:`to_json`'s text."""
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"settings are not JSON ({exc}); write them with to_json().") from exc
        return cls.from_dict(data)


def setting_fields() -> tuple[dataclasses.Field, ...]:
    """The fields of :class:`EnvSettings`, in keyword order."""
    return dataclasses.fields(EnvSettings)


def type_text(item: dataclasses.Field) -> str:
    """A field's type as the docs show it."""
    return item.metadata.get("type_text") or str(item.type)


def keyword_table() -> str:
    """The Markdown table of every keyword: name, command-line flag, type, default, doc."""
    lines = [
        "| keyword | flag | type | default | what it sets |",
        "|---|---|---|---|---|",
    ]
    for item in setting_fields():
        doc = item.metadata["doc"].replace("|", "\\|")
        kind = type_text(item).replace("|", "\\|")
        flag = "--" + item.name.replace("_", "-")
        lines.append(f"| `{item.name}` | `{flag}` | `{kind}` | `{item.default!r}` | {doc} |")
    return "\n".join(lines) + "\n"


# --- an environment's settings --------------------------------------------------------------
_DEFAULTS: dict[str, Any] = {item.name: item.default for item in dataclasses.fields(EnvSettings)}


def _differs(value: Any, default: Any) -> bool:
    try:
        return bool(value != default)
    except (TypeError, ValueError):  # e.g. an array compared with a str
        return True


def resolve_settings(
    scope: Mapping[str, Any], settings: Any = None, unknown: Mapping[str, Any] | None = None
) -> EnvSettings:
    """The settings of an environment made with the keywords of ``scope`` or ``settings``.

    Every value is checked once, before anything is built.

    Args:
        scope: ``SoArmEnv.__init__``'s arguments by name (its ``locals()``): a value for
            every field of :class:`EnvSettings`; the other names are left out.
        settings: a whole :class:`EnvSettings`, or None (the keywords are used).
        unknown: keywords that are no field: an error naming the closest ones.

    Raises:
        TypeError: an unknown keyword, ``settings`` that is no :class:`EnvSettings`, or
            ``settings`` beside keywords that differ from their defaults (a registered
            id's own ``task`` is allowed when the settings name the same task).
        ValueError: a bad value.
    """
    keywords = {name: scope[name] for name in _DEFAULTS}
    if unknown:  # an error naming the closest keywords, before anything is built
        EnvSettings.from_kwargs(**keywords, **unknown)
    if settings is None:
        return EnvSettings.from_kwargs(**keywords)
    if not isinstance(settings, EnvSettings):
        raise ArgumentTypeError(
            f"settings must be a gym_soarm.envs.settings.EnvSettings; got "
            f"{type(settings).__name__}. Build one with EnvSettings(...) or "
            "EnvSettings.from_kwargs(...)."
        )
    given = {k: v for k, v in keywords.items() if _differs(v, _DEFAULTS[k])}
    # A registered id passes its own task: fine when the settings name it too.
    if "task" in given and get_task(given["task"]).name == settings.task:
        del given["task"]
    if given:
        raise TypeError(
            f"pass either settings or keywords, not both; got settings and "
            f"{sorted(given)}. Use settings.replace({'=..., '.join(sorted(given))}=...)."
        )
    return settings


def setting_property(name: str, *, settable: bool = False) -> property:
    """A :class:`~gym_soarm.envs.env.SoArmEnv` attribute that reads the field ``name`` of
    its ``settings``.

    ``settable``: assigning it (``env.reward_type = "sparse"``, a vector env's
    ``set_attr``) replaces the environment's settings (its world's, ``env._world.settings``,
    which holds them) by a copy with the new value, checked; else assigning raises
    ``AttributeError``. Only fields that the environment reads anew each time may be
    settable: the world is built once.
    """

    def get(env: Any) -> Any:
        return getattr(env.settings, name)

    def set_(env: Any, value: Any) -> None:
        if not settable:
            raise AttributeError(
                f"{name} is fixed when the environment is made; make another one with "
                f"gym.make(..., {name}=...) (or settings=env.unwrapped.settings.replace(...))."
            )
        env._world.settings = env.settings.replace(**{name: value})

    (item,) = (item for item in setting_fields() if item.name == name)
    return property(get, set_, doc=f"The ``{name}`` setting: {item.metadata['doc']}.")


def merge_keywords(
    base: Mapping[str, Any], task: str, changes: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """``base`` keywords (e.g. a recipe's environment) with ``changes``, checked together
    for ``task`` as :class:`EnvSettings` checks them; only the keywords given are kept.

    Raises:
        ValueError, TypeError: an unknown keyword or a bad value.
    """
    merged = {**dict(base), **dict(changes or {})}
    EnvSettings.from_kwargs(**{"task": task, **merged})
    return merged
