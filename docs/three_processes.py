"""Draws docs/three_processes.png: the operator's three processes, and one real flight of them
(results/operator_flight: `uavsearch sitl --speedup 10 --seed 2018`, a pymavlink ground station
on UDP 14550, `uavsearch run --field out/sitl/field.json`). Run: python docs/three_processes.py"""

from __future__ import annotations

import json
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "results" / "operator_flight"


def _boxes(ax) -> None:
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 10)
    ax.axis("off")
    boxes = {
        "sitl": (0.3, 6.2, "1. uavsearch sitl\nvehicle: physics, camera,\nGPS, PX4-style MAVLink\nwrites field.json"),
        "gcs": (0.3, 0.6, "2. ground station\nmavproxy.py / QGC\nwatches, can take over"),
        "run": (5.6, 3.4, "3. uavsearch run\n--field field.json\ncompanion: estimator,\nmap, policy -> setpoints\nCtrl-C -> RTL, disarm"),
    }
    for x, y, text in boxes.values():
        ax.add_patch(plt.Rectangle((x, y), 4.1, 3.0, fc=(0.93, 0.95, 1.0), ec="tab:blue", lw=1.5))
        ax.text(x + 2.05, y + 1.5, text, ha="center", va="center", fontsize=7.5)
    arrow = dict(arrowstyle="<->", color="0.3", lw=1.3)
    ax.annotate("", xy=(5.6, 5.6), xytext=(4.4, 7.2), arrowprops=arrow)
    ax.text(5.0, 7.3, "UDP 14540\n(API link)", fontsize=7, ha="left")
    ax.annotate("", xy=(2.35, 3.6), xytext=(2.35, 6.2), arrowprops=arrow)
    ax.text(2.55, 4.8, "UDP 14550\n(GCS link)", fontsize=7)
    ax.set_title("three processes, as on a real drone", fontsize=9)


def _path(ax, log: dict, field: dict) -> None:
    c = np.array(log["cells"], dtype=float)
    w, h = field["width"], field["height"]
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_facecolor((0.86, 0.93, 0.82))
    ax.grid(True, color="0.85")
    ax.plot(c[:, 0], c[:, 1], "o-", color="tab:blue", ms=2.5, lw=1.0, alpha=0.8, label="decisions")
    ax.plot(c[0, 0], c[0, 1], "^", color="tab:orange", ms=9, label="start")
    ax.plot(c[-1, 0], c[-1, 1], "s", color="tab:green", ms=9, label="end")
    f = log["believed_found"]
    ax.plot(c[f, 0], c[f, 1], "*", color="tab:red", ms=13, label="target found")
    ax.legend(fontsize=6, loc="upper right")
    ax.set_title(f"the companion's search: {len(c) - 1} moves, {len(f)}/{field['targets']} found", fontsize=9)


def _station(ax, text: str) -> None:
    rows = re.findall(r"([\d.]+) s\s+armed (\w+)\s+mode (\S+)\s+alt\s+(-?[\d.]+) m", text)
    t = np.array([float(r[0]) for r in rows])
    armed = np.array([r[1] == "True" for r in rows])
    alt = np.array([float(r[3]) for r in rows])
    ax.plot(t, alt, color="tab:blue", lw=1.2, label="altitude (GPS, m)")
    ax.fill_between(t, 0, 4.5, where=armed, color="tab:orange", alpha=0.2, step="post", label="armed")
    changes = [(float(r[0]), r[2]) for i, r in enumerate(rows) if i == 0 or r[2] != rows[i - 1][2]]
    for x, mode in changes[1:]:
        ax.axvline(x, color="0.6", lw=0.6)
        ax.text(x, 4.7, mode.replace("AUTO.", ""), rotation=90, fontsize=6, va="bottom")
    ax.set_ylim(-3, 7)
    ax.set_xlabel("wall-clock s (speedup 10)", fontsize=8)
    ax.legend(fontsize=6, loc="lower center")
    ax.set_title("what the ground station saw", fontsize=9)


def main() -> None:
    log = json.loads((DATA / "search_log.json").read_text())
    field = json.loads((DATA / "field.json").read_text())
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    _boxes(axes[0])
    _path(axes[1], log, field)
    _station(axes[2], (DATA / "ground_station.txt").read_text())
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "three_processes.png", dpi=100)


if __name__ == "__main__":
    main()
