"""``python -m gym_soarm.sysid``: the dynamics fit's command line (:mod:`gym_soarm.cli.sysid`).

Importing this package runs nothing; the work itself is
:func:`gym_soarm.data.sysid.fit_dynamics`.
"""
