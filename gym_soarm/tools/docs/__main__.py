"""``python -m gym_soarm.tools.docs``: print the README's table of environments.

The program is :func:`gym_soarm.cli.docs.main`; this file only gives it its ``-m`` name.
"""

from __future__ import annotations

from gym_soarm.cli.docs import main

if __name__ == "__main__":
    main()
