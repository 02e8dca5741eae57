"""Which policy flies, and the check that it can fly this field before anything takes off."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from policy.base import Observation, Policy
from sim.gridworld import GridConfig

#: the policy a flight uses when the operator names none: the best shipped policy that flies.
#: (The one place to change it when a better one ships.) `belief` (policy/planner): 32.6 moves
#: on random 10 x 10 / 5 against the dual-stream network's 49.2, 36.3 at GPS sigma 1 m on the
#: probabilistic map against the network's 145.6 (results/search_quality.md); it flies any field
#: size and moving targets. The learned `searchnet` ties it on static random (32.63) and loses
#: on moving targets and 20 x 20, so the planner flies by default.
FLIGHT_POLICY = "belief"


_HINT = "the planners fly any field: --policy belief, frontier, ns or lawnmower"


class PolicyUnfit(ValueError):
    """This policy cannot fly this field; the message says why and what to do instead."""


def flight_policy(name: str | None, checkpoint: Path | None, grid: GridConfig, seed: int = 0) -> Policy:
    """Build the policy by registry name (or from a checkpoint alone), and make it decide once
    on a blank observation of this field, so a size it cannot serve is said before take-off."""
    from policy.baselines import known_policies, make_policy
    from policy.nn import CheckpointError

    if checkpoint is not None and not Path(checkpoint).exists():
        raise PolicyUnfit(f"checkpoint {checkpoint} does not exist")
    if name is None:
        name = FLIGHT_POLICY if checkpoint is None else _checkpoint_kind(Path(checkpoint))
    if name not in known_policies():
        raise PolicyUnfit(f"unknown policy {name!r}; known: {', '.join(known_policies())}")
    kw = {"checkpoint": checkpoint} if checkpoint is not None else {}
    try:
        policy = make_policy(name, cfg=grid, **kw)
    except (CheckpointError, FileNotFoundError, ValueError, KeyError, RuntimeError) as e:
        raise PolicyUnfit(f"policy {name!r} cannot fly a {grid.width} x {grid.height} field with "
                          f"{grid.n_targets} targets ({grid.motion}): {e}; {_HINT}") from e
    if policy.needs_truth:
        raise PolicyUnfit(f"policy {name!r} needs the field's truth (target positions); a companion computer "
                          "does not have it: pick one that searches")
    try:
        policy.reset(grid, 1, seed)
        a = int(policy.act(blank_observation(grid))[0])
    except Exception as e:  # noqa: BLE001 - whatever it is, it must show before take-off
        raise PolicyUnfit(f"policy {name!r} cannot decide on a {grid.width} x {grid.height} field "
                          f"({type(e).__name__}: {e}); {_HINT}") from e
    if not 0 <= a < grid.n_actions:
        raise PolicyUnfit(f"policy {name!r} answered action {a}; this field has {grid.n_actions} actions")
    return policy


def blank_observation(grid: GridConfig) -> Observation:
    """The first observation of a search in the field's middle: nothing seen, nothing visited."""
    from autopilot_bridge.view import valid_moves

    cell = np.array([grid.width // 2, grid.height // 2])
    view = np.zeros((1, 3, 3, 3), np.uint8)
    view[0, 2, 1, 1] = 1
    maps = np.zeros((1, grid.map_channels, grid.height, grid.width), np.float32)
    if grid.levels > 1:  # at level 1 in the levels' window, as the companion shows it (service)
        from autopilot_bridge.view import level_valid_moves, level_view

        return Observation(views=level_view(view[0], 1, grid.levels, cell, grid.width, grid.height)[None], maps=maps,
                           positions=cell[None].astype(np.int64), valid=level_valid_moves(cell, 1, grid)[None],
                           t=np.zeros(1, np.int64), active=np.ones(1, bool), found_now=np.zeros(1),
                           level=np.ones(1, np.int64))
    return Observation(views=view, maps=maps, positions=cell[None].astype(np.int64),
                       valid=valid_moves(cell, grid.width, grid.height, grid.n_actions)[None],
                       t=np.zeros(1, np.int64), active=np.ones(1, bool))


def _checkpoint_kind(path: Path) -> str:
    """A checkpoint alone: the DRQN's has its own format; every other is a dual-stream/SSN net."""
    from policy.nn import read_checkpoint

    try:
        doc = read_checkpoint(path)
    except Exception:  # noqa: BLE001 - not the network format: try the DRQN's
        return "drqn"
    mc = doc.get("model_config")
    model = mc.get("model") if isinstance(mc, dict) else getattr(mc, "model", None)
    return str(model or "dualstream")
