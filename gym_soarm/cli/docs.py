"""``python -m gym_soarm.tools.docs``: print the README's table of environments.

The table itself is :func:`gym_soarm.tools.docs.env_table`.
"""

from __future__ import annotations

from gym_soarm.tools.docs import env_table


def main() -> None:
    """Print the table of environments, generated from the registry."""
    print(env_table())


if __name__ == "__main__":
    main()
