"""The DRQN's training at a glance: reward and timeouts per episode, and the TD loss."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from provenance import atomic_open


def _smooth(x: Sequence[float], k: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Running mean over k, placed at the last index of each window."""
    x = np.asarray(x, dtype=float)
    if len(x) < k:
        return np.arange(len(x)), x
    return np.arange(k - 1, len(x)), np.convolve(x, np.ones(k) / k, mode="valid")


def plot_drqn_training(rewards: Sequence[float], timeouts: Sequence[bool], losses: Sequence[float], n_targets: int,
                       path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 3.8))
    ax[0].plot(*_smooth(rewards), label="targets found (reward)")
    ax[0].axhline(n_targets, color="grey", lw=0.8, ls=":")
    ax[0].set(xlabel="training episode", ylabel="targets per episode", title="DRQN training (50-episode mean)")
    tw = ax[0].twinx()
    ti, tv = _smooth(np.asarray(timeouts, dtype=float))
    tw.plot(ti, 100 * tv, color="C3", label="hit the step cap %")
    tw.set_ylabel("hit the step cap %", color="C3")
    ax[0].legend(loc="lower right", fontsize=8)
    ax[1].semilogy(*_smooth(losses, 200))
    ax[1].set(xlabel="training step", ylabel="squared TD error (masked)", title="loss (200-step mean)")
    fig.tight_layout()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=110)
    plt.close(fig)
    return Path(path)
