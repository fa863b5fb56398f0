"""The Warp backend's own kernel: each world's contacts, counted on the device.

MuJoCo Warp keeps every world's contacts in one shared pool (``Data.contact``, each
contact tagged with its ``worldid``); when the pool overflows it flags every world at
once, since it cannot tell whose contacts were dropped. :func:`count_contacts` counts the
contacts each world holds after a physics step, so that the backend
(:class:`~gym_soarm.sim.warp_backend.WarpBackend`) holds each world to its own budget and
truncates only the worlds that ran past it. Imported only with Warp installed (the
backend imports this module when it is built).
"""

from __future__ import annotations

import warp as wp


@wp.kernel
def count_contacts(
    nacon: wp.array(dtype=wp.int32),
    naconmax: wp.int32,
    worldid: wp.array(dtype=wp.int32),
    counts: wp.array(dtype=wp.int32),
):
    """Add each held contact (the first ``min(nacon, naconmax)`` of the pool) to its
    world's count in ``counts`` (one entry a world); launched with ``dim=naconmax``."""
    cid = wp.tid()
    if cid < wp.min(nacon[0], naconmax):
        wp.atomic_add(counts, worldid[cid], 1)


__all__ = ["count_contacts"]
