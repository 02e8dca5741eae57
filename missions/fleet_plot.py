"""The picture of a fleet's search: every vehicle's decided cells in its own colour, the team's
finds, and (for an in-process flight, scored) the true tracks and targets."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.gridworld import GridConfig

COLOURS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray")


def plot_fleet(path: Path, grid: GridConfig, cells: list[list], finds: list, title: str,
               tracks: list[np.ndarray] | None = None, targets: np.ndarray | None = None) -> None:
    """cells: per vehicle its decided cells (x, y); finds: (round, vehicle, cell); tracks: per
    vehicle (T, 2) true fractional cells; targets: (R, 2) true cells."""
    from missions.run_plot import field_axes, save_figure

    fig, ax = field_axes(grid, 5.8)
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
    save_figure(fig, ax, path, title)
