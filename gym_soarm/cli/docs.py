"""``python -m gym_soarm.cli.docs``: print the README's table of environments.

The README holds the table between ``<!-- env-table:start -->`` and
``<!-- env-table:end -->`` and a test keeps the two equal; ``docs/keywords.md`` is
:func:`keywords_page` (written by ``python -m gym_soarm.cli.settings_table``). Both
derive from the task registry and the settings, never by hand.
"""

from __future__ import annotations

from gym_soarm.tasks import BUILTIN_TASKS, get_task

ENV_TABLE_START = "<!-- env-table:start -->"
ENV_TABLE_END = "<!-- env-table:end -->"


def env_table() -> str:
    """The README's table of environments: one row per built-in task."""
    rows = [
        "| id | task | instruction | `max_episode_steps` | start |",
        "|---|---|---|---|---|",
    ]
    for name in BUILTIN_TASKS:
        spec = get_task(name)
        ids = ", ".join(f"`{env_id}`" for env_id in spec.env_ids)
        instruction = (
            spec.instructions[0]
            if len(spec.instructions) == 1
            else (
                " / ".join(f'"{s}"' for s in spec.instructions[:2])
                + (" ..." if len(spec.instructions) > 2 else "")
            )
        )
        start = "3 x 3 grid, 4 yaws" if spec.default_placement == "grid" else "anywhere in a region"
        rows.append(
            f"| {ids} | {spec.summary} | {instruction} | {spec.max_episode_steps} | {start} |"
        )
    from gym_soarm.tasks import ENV_IDS, TASK_ENV_IDS

    for env_id, (name, steps) in ENV_IDS.items():
        if env_id not in TASK_ENV_IDS:
            spec = get_task(name)
            rows.append(
                f"| `{env_id}` | preset: `{name}` as LeRobot's tabletop contract (cameras "
                f"`front` and `wrist`, follower units, 30 fps) | {spec.instructions[0]} | "
                f"{steps} | anywhere in a region |"
            )
    return "\n".join(rows)


KEYWORDS_PATH = "docs/keywords.md"
"""Where the keyword table lives, relative to the repository root."""


def keywords_page() -> str:
    """``docs/keywords.md``: every ``gym.make`` keyword, generated from
    :class:`gym_soarm.envs.settings.EnvSettings` (``python -m gym_soarm.cli.settings_table``)."""
    from gym_soarm.envs.settings import keyword_table

    return (
        "# gym.make keywords\n\n"
        "<!-- Generated from gym_soarm.envs.settings.EnvSettings by "
        "`python -m gym_soarm.cli.settings_table`; do not edit by hand. -->\n\n"
        'Every keyword of `gym.make("gym_soarm/<Task>-v0", ...)`, each a field of the frozen '
        "`gym_soarm.envs.settings.EnvSettings` that checks it (see [settings.md](settings.md)). "
        "`env.unwrapped.settings` holds an environment's; the programs' flags are the "
        "keywords' names with dashes (`dynamics` -> `--dynamics`). "
        "The docstring of `gym_soarm.envs.settings.EnvSettings` tells more of each.\n\n"
        + keyword_table()
    )


def main() -> None:
    """Print the table of environments, generated from the registry."""
    print(env_table())


if __name__ == "__main__":
    main()
