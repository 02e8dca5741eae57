"""The one interface every decision maker implements, learned or not.

A policy decides for a batch of episodes at once (the evaluation harness and the dataset
synthesis step many episodes in lock-step). It sees only what a real agent would see: the
view I, the map M, its own position and which moves stay on the map. Solvers and the oracle
additionally get the episodes' truth in `reset` and say so with `needs_truth = True`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from sim.gridworld import BatchGridWorld, Episodes, GridConfig


@dataclass(frozen=True)
class Observation:
    views: np.ndarray  # (n, 3, 3, 3) uint8 grid view, or (n, 3, H, W) uint8 rendered frame
    maps: np.ndarray  # (n, C, h, w) float32 visitation map M
    positions: np.ndarray  # (n, 2) agent cells (x, y)
    valid: np.ndarray  # (n, A) bool: actions that stay on the map
    t: np.ndarray  # (n,) moves made so far
    active: np.ndarray  # (n,) bool: episodes still running (act() may ignore the others)
    #: (n, h, w) float32 posterior over the agent's true cell under GPS noise (each row sums to
    #: 1); None = the position is known exactly (positions is the truth). With it, `positions`
    #: holds the estimate's most likely cell and `maps` the map built from the estimate.
    position_prob: np.ndarray | None = None
    #: (n, k, h, w) float32: k targets sighted beyond the 3 x 3 view (a real camera's frame edge
    #: shows the near end of a target one or two cells out), each as its likelihood over the
    #: field's cells (0 where it cannot stand; all-zero rows are padding); None = none. Static
    #: targets only (policy.belief.BeliefState folds them in; other policies ignore them).
    far_targets: np.ndarray | None = None
    #: (n,) targets found by the last move where the agent knows it exactly (the flight's
    #: companion counts a find when a target not found before is under the camera); None = the
    #: belief infers it from the view and the map (policy.belief.BeliefState._find_events)
    found_now: np.ndarray | None = None
    #: (n,) int altitude level flown (1..cfg.levels; docs/altitude.md); None = level 1 (the
    #: paper's world). With levels, views is (n, 4, W, W): the highest level's window of
    #: detections (sim.gridworld.BatchGridWorld._sampled_views)
    level: np.ndarray | None = None
    #: (n, h, w) bool searchable cells of each episode's field (sim.gridworld.masks): the
    #: drone knows the field it searches; masked cells hold no target and cannot be entered.
    #: None = the whole grid (every policy then behaves as before)
    mask: np.ndarray | None = None


def observe(world: BatchGridWorld, views: np.ndarray | None = None) -> Observation:
    """Observation of every episode of a world; `views` replaces I (e.g. rendered frames)."""
    v, m = world.observe()
    sampled = not world.cfg.perfect_detection
    return Observation(
        views=v if views is None else views,
        maps=m,
        positions=world.agent.copy(),
        valid=world.valid_actions(),
        t=world.t.copy(),
        active=~world.done,
        # with a sampled view the agent still knows each recovery (the close-up confirms it)
        found_now=world.found_now.astype(np.float64) if sampled else None,
        level=world.level.copy() if world.cfg.levels > 1 else None,
        mask=world.mask,
    )


class Policy(ABC):
    #: short name used by the CLI and in result tables
    name: str = "policy"
    #: True only for solvers and the oracle: they receive the episodes' truth in reset()
    needs_truth: bool = False
    #: what the world does with an off-map choice: "random" (Section V-A's random valid move) or
    #: "stay" (a wall bump leaves the agent in place: the DRQN's own world, where it learned)
    off_map: str = "random"

    @abstractmethod
    def reset(self, cfg: GridConfig, n: int, seed: int, episodes: Episodes | None = None) -> None:
        """Start n new episodes. Every random choice draws from a stream built from seed."""

    @abstractmethod
    def act(self, obs: Observation) -> np.ndarray:
        """(n,) int actions in 0 .. cfg.n_actions - 1; off-map choices are replaced by the world."""

    def loops(self) -> np.ndarray | None:
        """(n,) loops detected so far, for policies that run loop detection; else None."""
        return None


def random_valid(valid: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A uniformly random valid action per row of valid (m, A) bool."""
    keys = rng.random(valid.shape)
    keys[~valid] = -1.0
    return keys.argmax(axis=1)
