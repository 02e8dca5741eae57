"""The DRQN's training rule for moves off the map: the agent bumps the wall and stays, and
the move still counts (the authors' DRQN environment). Our BatchGridWorld instead replaces an
off-map move by a random valid one (the paper's Section V-A rule, used at evaluation for every
policy), so training steps the world through this wrapper.

Bumping episodes are held still for one world step (marked done for its duration, so the
world ignores them), then their clock advances by one move, and a target that walked onto
the waiting agent counts as recovered, as it would in the world.
"""

from __future__ import annotations

import numpy as np

from sim.gridworld import BatchGridWorld


def step_with_bumps(world: BatchGridWorld, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Step every running episode; returns (targets newly found (n,), bumped (n,) bool)."""
    a = np.asarray(actions, dtype=np.int64)
    if a.shape != (world.n,):
        raise ValueError(f"expected {world.n} actions, got shape {a.shape}")
    if (a < 0).any() or (a >= world.n_actions).any():
        raise ValueError(f"actions must be in 0..{world.n_actions - 1} for this config")
    rows = np.arange(world.n)
    valid = world.valid_actions()
    bump = ~world.done & ~valid[rows, a]
    if not bump.any():
        return world.step(a), bump
    safe = np.where(bump, valid.argmax(axis=1), a)  # ignored by the world: those rows are held
    world.done[bump] = True
    try:
        newly = world.step(safe)
    finally:
        world.done[bump] = False
    world.t[bump] += 1
    hits = np.all(world.targets() == world.agent[:, None, :], axis=-1) & ~world.found & bump[:, None]
    if hits.any():
        world.found |= hits
        world.find_moves[hits] = np.broadcast_to(world.t[:, None], hits.shape)[hits]
        got = hits.any(axis=1)
        world.met[rows[got], world.agent[got, 1], world.agent[got, 0]] = True
        newly = newly + hits.sum(axis=1)
    world.done[bump] |= world.found[bump].all(axis=1) | (world.t[bump] > world.cfg.t_e)
    return newly, bump
