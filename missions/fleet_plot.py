"""The picture of a fleet's search: every vehicle's decided cells in its own colour, the team's
finds, and (for an in-process flight, scored) the true tracks and targets."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from provenance import atomic_open
from sim.gridworld import GridConfig

COLOURS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray")


def plot_fleet(path: Path, grid: GridConfig, cells: list[list], finds: list, title: str,
               tracks: list[np.ndarray] | None = None, targets: np.ndarray | None = None) -> None:
    """cells: per vehicle its decided cells (x, y); finds: (round, vehicle, cell); tracks: per
    vehicle (T, 2) true fractional cells; targets: (R, 2) true cells."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.8, 5.8))
    ax.set_xlim(-0.5, grid.width - 0.5)
    ax.set_ylim(grid.height - 0.5, -0.5)
    step = max(1, grid.width // 10)
    ax.set_xticks(range(0, grid.width, step))
    ax.set_yticks(range(0, grid.height, step))
    ax.grid(True, color="0.85")
    ax.set_facecolor((0.86, 0.93, 0.82))
    for i, cs in enumerate(cells):
        col = COLOURS[i % len(COLOURS)]
        if tracks is not None and i < len(tracks) and len(tracks[i]):
            ax.plot(tracks[i][:, 0], tracks[i][:, 1], "-", color=col, alpha=0.35, lw=1)
        c = np.array(cs, dtype=float).reshape(-1, 2)
        if len(c):
            ax.plot(c[:, 0], c[:, 1], "o-", color=col, ms=3, lw=1.5, label=f"vehicle {i}")
            ax.plot(c[0, 0], c[0, 1], "^", color=col, ms=10)
            ax.plot(c[-1, 0], c[-1, 1], "s", color=col, ms=9)
    if targets is not None and len(targets):
        ax.plot(targets[:, 0], targets[:, 1], "X", color="tab:red", ms=12, label="targets (truth)")
    if finds:
        f = np.array([c for _, _, c in finds], dtype=float)
        ax.plot(f[:, 0], f[:, 1], "*", color="gold", mec="k", ms=14, label="found by the team")
    ax.set_title(title, fontsize=9)
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    with atomic_open(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)
