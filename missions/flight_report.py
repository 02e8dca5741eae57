"""`report.md`: the page a person opens first after a flight. What was flown (path with start
and end over the true targets), what the companion believed it covered (the final visitation
map), what the camera showed and what the detector made of it, how far the position estimate
was from the truth over time, and the one-line summary. Figures are PNGs written atomically
beside it; the numbers come from report.json and search_log.json of the same flight."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from provenance import atomic_open


def _fig():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> None:
    plt = _fig()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=100)
    plt.close(fig)


def summary_line(r: dict[str, Any]) -> str:
    parts = [f"{r['moves']} moves"]
    if r.get("grid_moves") is not None and r.get("flight_grid_ratio") is not None:
        parts.append(f"grid world {r['grid_moves']} (flight/grid {r['flight_grid_ratio']:.2f})")
    parts.append(f"optimal {r['optimal_moves']}")
    parts.append(f"found {r['truly_found']}/{r['targets']} (truth), believed {r['believed_found']}")
    if r.get("nees_mean") is not None:
        parts.append(f"mean NEES {r['nees_mean']:.2f} (2 expected)")
    parts.append(f"{r['simulated_s']:.0f} s simulated in {r['wall_s']:.0f} s")
    line = "; ".join(parts)
    return line + (f"; error: {r['error']}" if r.get("error") else "")


def plot_visitation(path: Path, visited: np.ndarray, met: np.ndarray, cells: list, targets: np.ndarray) -> None:
    plt = _fig()
    fig, ax = plt.subplots(figsize=(5, 4.4))
    im = ax.imshow(visited, vmin=0, vmax=1, cmap="Blues")
    fig.colorbar(im, ax=ax, label="P(visited)")
    ys, xs = np.nonzero(met > 0.5)
    ax.plot(xs, ys, "o", mfc="none", mec="tab:orange", ms=14, mew=2, label="believed found")
    ax.plot(targets[:, 0], targets[:, 1], "X", color="tab:red", ms=9, label="targets (truth)")
    c = np.asarray(cells)
    ax.plot(c[0, 0], c[0, 1], "^", color="tab:green", ms=10, label="start")
    ax.plot(c[-1, 0], c[-1, 1], "s", color="black", ms=8, label="end")
    ax.set_title("final visitation map (the companion's belief)", fontsize=9)
    ax.legend(loc="upper right", fontsize=6)
    fig.tight_layout()
    _save(fig, path)


def plot_frames(path: Path, frames: list[tuple[int, np.ndarray, list]], cells: list) -> None:
    """Camera frames with the 3 x 3 cells the detector judged (red: a target there)."""
    plt = _fig()
    n = len(frames)
    cols = min(n, 4)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.4 * cols, 2.6 * rows), squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, (move, frame, seen) in zip(axes.ravel(), frames, strict=False):
        h, w = frame.shape[:2]
        ax.imshow(frame)
        cell_px = w * 2.0 / (2 * 3.5 * np.tan(np.radians(50)))  # 2 m cells at 3.5 m, 100 deg FoV
        for r in range(3):
            for k in range(3):
                x0, y0 = w / 2 + (k - 1.5) * cell_px, h / 2 + (r - 1.5) * cell_px
                hit = bool(seen[r][k])
                ax.add_patch(plt.Rectangle((x0, y0), cell_px, cell_px, fill=False, lw=2 if hit else 0.6,
                                           ec="red" if hit else "white"))
        c = cells[move] if move < len(cells) else None
        ax.set_title(f"move {move} cell {tuple(c) if c is not None else ''}", fontsize=7)
    fig.suptitle("camera frames; red: the detector saw a target in that cell", fontsize=8)
    fig.tight_layout()
    _save(fig, path)


def plot_estimate(path: Path, times: list, means: list, covs: list, true_ne: list, nees: list) -> None:
    plt = _fig()
    t, m, c, x = np.asarray(times), np.asarray(means), np.asarray(covs), np.asarray(true_ne)
    fig, axes = plt.subplots(3, 1, figsize=(7, 6.4), sharex=True)
    for i, name in enumerate(("north", "east")):
        sd = np.sqrt(c[:, i, i])
        axes[i].fill_between(t, m[:, i] - 2 * sd, m[:, i] + 2 * sd, color="tab:blue", alpha=0.2, label="estimate ± 2 sd")
        axes[i].plot(t, m[:, i], "-", color="tab:blue", lw=1, label="estimate")
        axes[i].plot(t, x[:, i], "-", color="black", lw=1, label="truth (simulator)")
        axes[i].set_ylabel(f"{name} (m)")
        axes[i].legend(loc="upper right", fontsize=6)
    axes[2].plot(t, nees, ".-", color="tab:purple", lw=0.8)
    axes[2].axhline(2.0, color="0.5", ls="--", lw=0.8)
    axes[2].axhline(5.991, color="tab:red", ls=":", lw=0.8)
    axes[2].set_ylabel("NEES")
    axes[2].set_xlabel("simulated time (s)")
    axes[0].set_title("position estimate at each decision vs the truth (2: expected NEES, red: 95 % bound)",
                      fontsize=8)
    fig.tight_layout()
    _save(fig, path)


def write_report(out: Path, r: dict[str, Any], log: dict[str, Any], visited: np.ndarray | None,
                 met: np.ndarray | None, targets: np.ndarray, frames: list) -> Path:
    """Write out/report.md and its figures; returns the path of report.md."""
    out = Path(out)
    figs: list[tuple[str, str]] = []
    if Path(out / "search.png").exists():
        figs.append(("The flown path", "search.png"))
    cells = log.get("cells", [])
    if visited is not None and cells:
        plot_visitation(out / "visitation.png", visited, met if met is not None else np.zeros_like(visited),
                        cells, targets)
        figs.append(("Final visitation map", "visitation.png"))
    if frames:
        plot_frames(out / "frames.png", frames, cells)
        figs.append(("Camera frames and detections", "frames.png"))
    if log.get("times_s") and log.get("true_ne"):
        plot_estimate(out / "estimate.png", log["times_s"], log["posterior_mean_ne"], log["posterior_cov_ne"],
                      log["true_ne"], r.get("nees") or [0.0] * len(log["times_s"]))
        figs.append(("Position estimate vs truth", "estimate.png"))
    lines = [
        f"# Search flight: seed {r.get('seed')}, policy {r.get('policy', '?')}",
        "",
        f"**{summary_line(r)}**",
        "",
        f"Outcome: {_outcome(r.get('outcome'))}."
        f" Decisions every {r.get('decision_period_s')} simulated s; schedule slips {r.get('schedule_slips')}, late "
        f"frames {r.get('late_frames')}, inputs waited for in vain {r.get('late_inputs')}; frames {r.get('frames')} (missing {r.get('frames_missing')}); visitation map: "
        f"{r.get('visit_map')}; mean position sd {_f(r.get('mean_posterior_sd_m'))} m; "
        f"{_pct(r.get('nees_inside_95'))} of decisions inside the 95 % NEES bound. Git {r.get('git_revision')}.",
        "",
        "Files: `report.json` (numbers and provenance), `search_log.json` (every decision), `flight.tlog` "
        "(MAVLink, open with mavlogdump.py or MAVExplorer).",
        "",
    ]
    for title, name in figs:
        lines += [f"## {title}", "", f"![{title}]({name})", ""]
    with atomic_open(out / "report.md", "w") as f:
        f.write("\n".join(lines))
    return out / "report.md"


def _f(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.2f}"


def _pct(x: float | None) -> str:
    return "n/a" if x is None else f"{100 * x:.0f} %"


def _outcome(o: Any) -> str:
    if isinstance(o, dict):
        return f"exit code {o.get('exit_code')}" + (f", {o['cause']}" if o.get("cause") else ", search complete")
    return "n/a" if o is None else str(o)
