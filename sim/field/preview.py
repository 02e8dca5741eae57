"""field.png: the grid's cells coloured by class over the polygon, in local metres (east
right, north up), so an operator sees before flying what will be searched and what not."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from provenance import atomic_write_bytes

from .mask import FORBIDDEN, OUTSIDE, SEARCHABLE
from .model import PolygonField

COLOURS = {SEARCHABLE: "#8cc56a", OUTSIDE: "#e8e8e8", FORBIDDEN: "#d9694f"}


def render_png(f: PolygonField, title: str = "") -> bytes:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Patch

    xs, ys = np.meshgrid(np.arange(f.width), np.arange(f.height))
    cells = np.stack([xs.ravel(), ys.ravel()], axis=-1)
    corners = f.frame.cell_corners(cells)[..., ::-1]  # (east, north) for the plot
    colours = [COLOURS[int(c)] for c in f.classes.ravel()]
    fig, ax = plt.subplots(figsize=(7, 7), dpi=110)
    ax.add_collection(PolyCollection(corners, facecolors=colours, edgecolors="white", linewidths=0.4))
    outer, no_fly = f.rings_ne()
    ring = np.vstack([outer, outer[:1]])
    ax.plot(ring[:, 1], ring[:, 0], color="#1f4e79", lw=2.0)
    for z, r in zip(f.no_fly, no_fly, strict=True):
        rr = np.vstack([r, r[:1]])
        ax.plot(rr[:, 1], rr[:, 0], color="#7a1f12", lw=1.6, ls="-" if z.kind == "hole" else "--")
        if z.name:
            ax.annotate(z.name, (r[:, 1].mean(), r[:, 0].mean()), ha="center", va="center", fontsize=8)
    o = f.cell_to_ned((0, 0))
    fwd = f.cell_to_ned((0, -2)) - o  # two cells along f (-y)
    right = f.cell_to_ned((2, 0)) - o
    ax.annotate("", (o[1] + fwd[1], o[0] + fwd[0]), (o[1], o[0]), arrowprops={"arrowstyle": "->", "color": "k"})
    ax.annotate("", (o[1] + right[1], o[0] + right[0]), (o[1], o[0]), arrowprops={"arrowstyle": "->", "color": "k"})
    ax.annotate("f (-y)", (o[1] + fwd[1], o[0] + fwd[0]), fontsize=7)
    ax.annotate("r (+x)", (o[1] + right[1], o[0] + right[0]), fontsize=7)
    ax.plot([o[1]], [o[0]], "ko", ms=3)
    n = f.counts()
    total = f.width * f.height
    ax.legend(handles=[Patch(color=COLOURS[SEARCHABLE], label=f"searchable {n['searchable']}"),
                       Patch(color=COLOURS[FORBIDDEN], label=f"forbidden {n['forbidden']}"),
                       Patch(color=COLOURS[OUTSIDE], label=f"outside {n['outside']}")],
              loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    ax.set_title(f"{title}\n{f.width} x {f.height} cells of {f.cell_m:g} m, heading {f.heading_deg:.2f} deg, "
                 f"{100 * n['searchable'] / total:.1f} % searchable", fontsize=9)
    ax.set_xlabel("east (m) from cell (0, 0)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal")
    ax.autoscale_view()
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def write_png(path: Path | str, f: PolygonField, title: str = "") -> None:
    atomic_write_bytes(path, render_png(f, title))
