"""The real arm: its units (:mod:`~gym_soarm.real.units`, :mod:`~gym_soarm.real.unit_maps`),
a follower's calibration (:mod:`~gym_soarm.real.calibration`), fitted dynamics
(:mod:`~gym_soarm.real.dynamics`), reading a recorded dataset
(:mod:`~gym_soarm.real.dataset`), its replay (:mod:`~gym_soarm.real.replay`) and the
system identification that fits the dynamics to it (:mod:`~gym_soarm.real.sysid`).
"""
