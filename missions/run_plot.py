"""The companion's own picture of a search: the cells it decided, where it believed it found
targets, its position uncertainty. Only what the companion knows: no truth (the scored plot of
an in-process flight is missions/flight.py's)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from provenance import atomic_open
from sim.gridworld import GridConfig


def field_axes(grid: GridConfig, size_in: float = 5.5):
    """A figure and axes laid out as the field: cells (x right, y down), grass-coloured (the
    companion's plots and the fleet's, missions/fleet_plot.py)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(size_in, size_in))
    ax.set_xlim(-0.5, grid.width - 0.5)
    ax.set_ylim(grid.height - 0.5, -0.5)
    step = max(1, grid.width // 10)
    ax.set_xticks(range(0, grid.width, step))
    ax.set_yticks(range(0, grid.height, step))
    ax.grid(True, color="0.85")
    ax.set_facecolor((0.86, 0.93, 0.82))
    return fig, ax


def save_figure(fig, ax, path: Path, title: str, fontsize: int = 9) -> None:
    """Title, legend, and the PNG written atomically; the figure closed."""
    import matplotlib.pyplot as plt

    ax.set_title(title, fontsize=fontsize)
    ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    with atomic_open(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)


def plot_decisions(path: Path, grid: GridConfig, cells: list, found_moves: list[int], sd_m: list[float],
                   title: str) -> None:
    c = np.array(cells, dtype=float).reshape(-1, 2)
    fig, ax = field_axes(grid)
    if len(c):
        ax.plot(c[:, 0], c[:, 1], "o-", color="tab:blue", ms=3, lw=1.5, label="decisions (cells)")
        ax.plot(c[0, 0], c[0, 1], "^", color="tab:orange", ms=10, label="start")
        ax.plot(c[-1, 0], c[-1, 1], "s", color="tab:green", ms=10, label="end")
        f = [m for m in found_moves if m < len(c)]
        if f:
            ax.plot(c[f, 0], c[f, 1], "*", color="tab:red", ms=14, label="target believed found")
    sd = f"; position sd {np.mean(sd_m):.2f} m" if sd_m else ""
    save_figure(fig, ax, path, title + sd)
