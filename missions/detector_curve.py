"""What the companion's detector sees from each flying height: p_d(level, ring) and false alarms,
measured on the SITL's own camera and scene against its truth (`uavsearch detector-curve`).

The grid world's altitude levels (issue 27) see a (2 r + 1)^2 window of radius r(l) = l from
h(l) = 3.5 m * (2 r + 1) / 3 (the 100 deg camera's margin round the window as today's 3 x 3 at
3.5 m). Its detection model needs, per level, the chance a target in view is seen in its cell
by its ring (the Chebyshev distance in cells from the nadir cell, 0..r) and the chance an empty
cell in view is lit. Those numbers are measured here, not invented:

- the field is `sim.vehicle.scene.FieldScene`, the SITL's: its episode placed by the grid
  world's model, its cows built, coated and turned by `sim.vehicle.field.Field`, the track
  round the grass; a fresh field (episode and scene seeds from the run's seed) every
  `frames_per_field` frames;
- the vehicle is over a cell at the level's height as it hovers there in flight: off the cell's
  centre by the position error flown (`hover_sd_m`, per axis: flights of seeds 2 and the demo
  hovered 0.28-0.56 m sd off their cells), at a true height off the commanded one by the
  barometer's drift (`sim.vehicle.gps.GpsConfig.baro_sigma_m`: the autopilot holds height on it,
  the companion reads the commanded height), the gimbal a little off nadir and north;
- half the frames are over a cell at a ring drawn evenly from 0..r of a target (so every ring
  has targets to count: a random cell has a target under it one time in forty), the others
  over a cell drawn evenly from the field (the false alarms of a field as it is: counted on
  those only, so the cells beside a target are not over-weighted);
- the companion's detector (`autopilot_bridge.detection.detector.find_blobs`, told the height flown)
  finds the blobs and puts each in a cell of the window (`window_cells`, the camera's offset
  from its cell known: the detector's part, not the estimator's). A target in view is seen
  when its cell is lit; an empty on-field cell in view that is lit is a false alarm.

Intervals are Clopper-Pearson 95 %. Nothing here imports the grid world's policies: the table is
an input of theirs (`sim/gridworld/data/detection.json`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

FORMAT = "uavsearch.detection/1"
#: the height of level 1 (m), today's flights
BASE_HEIGHT_M = 3.5


def view_radius(level: int) -> int:
    """The grid world's view radius (cells) at altitude level `level` (1: today's 3 x 3)."""
    return int(level)


def level_height_m(level: int) -> float:
    """The flying height (m) of level `level`: the window's margin inside the 100 deg camera's
    footprint as today's 3 x 3 at 3.5 m (3.5, 5.83, 8.17 m for levels 1-3)."""
    return BASE_HEIGHT_M * (2 * view_radius(level) + 1) / 3


@dataclass(frozen=True)
class CurveConfig:
    frames: int = 9000  # in all, dealt evenly to the levels
    seed: int = 0
    camera_px: int = 50
    levels: tuple[int, ...] = (1, 2, 3)
    width: int = 20
    height: int = 20
    n_targets: int = 10
    distribution: str = "random"
    field_edge: bool = True
    frames_per_field: int = 30
    hover_sd_m: float = 0.45
    baro_sd_m: float = 0.2
    gimbal_sd_deg: float = 0.5
    yaw_sd_deg: float = 1.0
    #: the error of the camera's position as the companion believes it (m, per axis); 0: known
    position_sd_m: float = 0.0

    def __post_init__(self) -> None:
        from sim.vehicle.scene import check_camera_px

        if isinstance(self.frames, bool) or not isinstance(self.frames, int) or self.frames < len(self.levels):
            raise ValueError(f"frames must be a whole number >= one per level ({len(self.levels)}; got {self.frames!r})")
        check_camera_px(self.camera_px)
        if not self.levels or any(not isinstance(v, int) or v < 1 for v in self.levels) or \
                len(set(self.levels)) != len(self.levels):
            raise ValueError(f"levels must be distinct whole numbers >= 1 (got {self.levels!r})")
        if self.frames_per_field < 1:
            raise ValueError(f"frames_per_field must be >= 1 (got {self.frames_per_field})")
        for name in ("hover_sd_m", "baro_sd_m", "gimbal_sd_deg", "yaw_sd_deg", "position_sd_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0 (got {v!r})")
        if self.width < 1 or self.height < 1 or not 1 <= self.n_targets <= self.width * self.height:
            raise ValueError(f"the field must be at least 1 x 1 with 1..cells targets (got {self.width} x "
                             f"{self.height}, {self.n_targets} targets)")

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["levels"] = list(self.levels)
        return d


@dataclass
class Counts:
    """Per level: targets in view and those seen, by ring; empty on-field cells in view and the
    lit ones (false alarms), over the uniform frames and over all."""

    radius: int
    targets: np.ndarray = field(init=False)
    seen: np.ndarray = field(init=False)
    empty: int = 0
    false_alarms: int = 0
    empty_all: int = 0
    false_alarms_all: int = 0
    frames: int = 0

    def __post_init__(self) -> None:
        self.targets = np.zeros(self.radius + 1, dtype=np.int64)
        self.seen = np.zeros(self.radius + 1, dtype=np.int64)


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact (Clopper-Pearson) interval of a binomial proportion k / n; (0, 1) for n = 0."""
    from scipy.stats import beta

    if n == 0:
        return 0.0, 1.0
    a = (1 - level) / 2
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a, k + 1, n - k))
    return lo, hi


def _seed(*parts: int) -> int:
    """A 31-bit seed for a component from the run's seed and the component's indices."""
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(1)[0] & 0x7FFFFFFF)


def _ring_cell(rng: np.random.Generator, target: np.ndarray, ring: int, width: int, height: int) -> np.ndarray | None:
    """A cell drawn evenly from those at Chebyshev distance `ring` from target on the field."""
    d = np.arange(-ring, ring + 1)
    dx, dy = np.meshgrid(d, d, indexing="xy")
    on_ring = np.maximum(np.abs(dx), np.abs(dy)) == ring
    cells = np.stack([target[0] + dx[on_ring], target[1] + dy[on_ring]], axis=1)
    cells = cells[(cells[:, 0] >= 0) & (cells[:, 0] < width) & (cells[:, 1] >= 0) & (cells[:, 1] < height)]
    return None if len(cells) == 0 else cells[rng.integers(len(cells))]


def measure(cfg: CurveConfig, on_frame: Callable[[int], None] | None = None) -> dict[int, Counts]:
    """Render cfg.frames frames and count what the detector saw against the truth, per level."""
    import pybullet as p

    from autopilot_bridge.detection.detector import DetectorConfig, find_blobs, window_cells
    from sim.gridworld import GridConfig, cell_to_ned
    from sim.vehicle.camera import CAMERA_BELOW_M
    from sim.vehicle.geo import HomePosition
    from sim.vehicle.scene import FieldScene

    grid = GridConfig(width=cfg.width, height=cfg.height, n_targets=cfg.n_targets, distribution=cfg.distribution)
    det = DetectorConfig()
    counts = {lv: Counts(view_radius(lv)) for lv in cfg.levels}
    rng = np.random.default_rng([cfg.seed, 0xDE7C])
    gimbal, yaw = math.radians(cfg.gimbal_sd_deg), math.radians(cfg.yaw_sd_deg)
    cid = p.connect(p.DIRECT)
    scene = None
    try:
        for i in range(cfg.frames):
            block = i // cfg.frames_per_field
            if i % cfg.frames_per_field == 0:  # a fresh field, as a SITL of this seed lays it
                p.resetSimulation(physicsClientId=cid)
                scene = FieldScene(grid, HomePosition(), _seed(cfg.seed, block, 1), 4.0)
                scene.attach(cid, _seed(cfg.seed, block, 2), cfg.field_edge, cfg.camera_px)
                scene.update_targets(0.0)
                targets = scene.episode.targets[0].astype(int)
            level = cfg.levels[i % len(cfg.levels)]
            r, h = view_radius(level), level_height_m(level)
            uniform = (i // len(cfg.levels)) % 2 == 1
            cell = None
            if not uniform:
                cell = _ring_cell(rng, targets[rng.integers(len(targets))], int(rng.integers(r + 1)),
                                  cfg.width, cfg.height)
            if cell is None:
                cell = np.array([rng.integers(cfg.width), rng.integers(cfg.height)])
            offset = rng.normal(0.0, cfg.hover_sd_m, 2)  # (north, east) m off the cell's centre
            true_h = h + rng.normal(0.0, cfg.baro_sd_m)
            att = (rng.normal(0.0, gimbal), rng.normal(0.0, gimbal), rng.normal(0.0, yaw))
            believed = offset + rng.normal(0.0, cfg.position_sd_m, 2) if cfg.position_sd_m else offset
            ne = cell_to_ned(cell) + offset - scene.spawn_ne
            frame = scene.render(0.0, np.array([ne[0], ne[1], -true_h]), 0.0, att)
            camera_h = h - CAMERA_BELOW_M  # as the companion reads it: the height it commanded
            blobs = find_blobs(frame, det, camera_h)
            lit = np.zeros((2 * r + 1, 2 * r + 1), dtype=bool)
            for rc in window_cells(blobs, believed, camera_h, r):
                if rc is not None:
                    lit[rc] = True
            _count(counts[level], lit, cell, targets, cfg.width, cfg.height, uniform)
            if on_frame is not None:
                on_frame(i)
    finally:
        if p.isConnected(cid):
            p.disconnect(cid)
    return counts


def _count(c: Counts, lit: np.ndarray, cell: np.ndarray, targets: np.ndarray, width: int, height: int,
           uniform: bool) -> None:
    """Add one frame's window (lit cells) against the truth (targets' cells) to c."""
    r = c.radius
    d = np.arange(-r, r + 1)
    dy, dx = np.meshgrid(d, d, indexing="ij")  # window rows north to south: y grows southwards
    xs, ys = cell[0] + dx, cell[1] + dy
    on_field = (xs >= 0) & (xs < width) & (ys >= 0) & (ys < height)
    occupied = np.zeros_like(on_field)
    for tx, ty in targets:
        row, col = ty - cell[1] + r, tx - cell[0] + r
        if 0 <= row <= 2 * r and 0 <= col <= 2 * r:
            occupied[row, col] = True
            ring = max(abs(row - r), abs(col - r))
            c.targets[ring] += 1
            c.seen[ring] += int(lit[row, col])
    empty = on_field & ~occupied
    n_empty, n_fa = int(empty.sum()), int((lit & empty).sum())
    c.empty_all += n_empty
    c.false_alarms_all += n_fa
    if uniform:
        c.empty += n_empty
        c.false_alarms += n_fa
    c.frames += 1


def table(cfg: CurveConfig, counts: dict[int, Counts], **provenance: Any) -> dict[str, Any]:
    """The detection table in the grid world's format (`FORMAT`), with counts and intervals."""
    from provenance import stamp

    levels = list(cfg.levels)
    p_d, p_ci, fa, fa_ci, fa_all, fa_all_ci = [], [], [], [], [], []
    for lv in levels:
        c = counts[lv]
        p_d.append([round(float(k / n), 4) if n else 0.0 for k, n in zip(c.seen, c.targets, strict=True)])
        p_ci.append([[round(v, 4) for v in clopper_pearson(int(k), int(n))] for k, n in zip(c.seen, c.targets, strict=True)])
        fa.append(round(c.false_alarms / c.empty, 6) if c.empty else 0.0)
        fa_ci.append([round(v, 6) for v in clopper_pearson(c.false_alarms, c.empty)])
        fa_all.append(round(c.false_alarms_all / c.empty_all, 6) if c.empty_all else 0.0)
        fa_all_ci.append([round(v, 6) for v in clopper_pearson(c.false_alarms_all, c.empty_all)])
    return {
        "format": FORMAT,
        "levels": levels,
        "height_m": [round(level_height_m(lv), 2) for lv in levels],
        "view_radius": [view_radius(lv) for lv in levels],
        "p_detect": p_d,
        "false_alarm_per_cell": fa,
        "frames": cfg.frames,
        "intervals": {
            "method": "Clopper-Pearson 95 %",
            "p_detect": p_ci,
            "false_alarm_per_cell": fa_ci,
            "counts": {
                "frames": [counts[lv].frames for lv in levels],
                "targets": [counts[lv].targets.tolist() for lv in levels],
                "seen": [counts[lv].seen.tolist() for lv in levels],
                "empty_cells": [counts[lv].empty for lv in levels],
                "false_alarms": [counts[lv].false_alarms for lv in levels],
            },
            "false_alarm_per_cell_all_frames": fa_all,
            "false_alarm_per_cell_all_frames_interval": fa_all_ci,
        },
        "provenance": stamp(cfg.to_dict(), cfg.seed, **provenance),
    }


def write_curve(doc: dict[str, Any], out: Path, command: str) -> list[Path]:
    """DIR/detection.json (the table), DIR/report.md (the table, the counts, the command) and
    DIR/curve.png (p_d against ring per level, with the intervals), each written atomically."""
    from provenance import atomic_write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "detection.json", out / "report.md", out / "curve.png"]
    atomic_write_json(paths[0], doc)
    _write_report(paths[1], doc, command)
    _plot(paths[2], doc)
    return paths


def _write_report(path: Path, doc: dict[str, Any], command: str) -> None:
    from provenance import atomic_open

    cfg, iv = doc["provenance"]["config"], doc["intervals"]
    cnt = iv["counts"]
    lines = [
        "# Detection from each flying height: the companion's detector on the SITL's camera",
        "",
        f"`{command}`",
        "",
        f"{doc['frames']} frames ({', '.join(str(n) for n in cnt['frames'])} per level), "
        f"{cfg['camera_px']} x {cfg['camera_px']} px, 100 deg FoV; seed {cfg['seed']}; "
        f"fields {cfg['width']} x {cfg['height']} / {cfg['n_targets']} ({cfg['distribution']}), "
        f"a fresh one every {cfg['frames_per_field']} frames; hover {cfg['hover_sd_m']} m sd off the cell, "
        f"barometer {cfg['baro_sd_m']} m sd, gimbal {cfg['gimbal_sd_deg']} deg / yaw {cfg['yaw_sd_deg']} deg sd, "
        f"believed position error {cfg['position_sd_m']} m sd. Git revision {doc['provenance']['git_revision']}.",
        "",
        "p_d: the chance a target in view lights its own cell, by ring (Chebyshev distance in cells "
        "from the nadir cell); false alarms: lit empty on-field cells in view, per cell, over the frames "
        "over a cell drawn evenly from the field (all frames, with those beside a target: in brackets). "
        "Clopper-Pearson 95 % intervals.",
        "",
        "| level | height (m) | radius | ring | targets | seen | p_d | 95 % interval |",
        "|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for i, lv in enumerate(doc["levels"]):
        for ring, pd in enumerate(doc["p_detect"][i]):
            lo, hi = iv["p_detect"][i][ring]
            lines.append(f"| {lv} | {doc['height_m'][i]:g} | {doc['view_radius'][i]} | {ring} | "
                         f"{cnt['targets'][i][ring]} | {cnt['seen'][i][ring]} | {pd:.4f} | {lo:.4f}-{hi:.4f} |")
    lines += ["", "| level | empty cells | false alarms | per cell | 95 % interval | all frames |",
              "|---:|---:|---:|---:|---|---:|"]
    for i, lv in enumerate(doc["levels"]):
        lo, hi = iv["false_alarm_per_cell"][i]
        lines.append(f"| {lv} | {cnt['empty_cells'][i]} | {cnt['false_alarms'][i]} | "
                     f"{doc['false_alarm_per_cell'][i]:.6f} | {lo:.6f}-{hi:.6f} | "
                     f"({iv['false_alarm_per_cell_all_frames'][i]:.6f}) |")
    with atomic_open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def _plot(path: Path, doc: dict[str, Any]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from provenance import atomic_open

    fig, ax = plt.subplots(figsize=(6, 4))
    for i, lv in enumerate(doc["levels"]):
        pd = np.asarray(doc["p_detect"][i])
        ci = np.asarray(doc["intervals"]["p_detect"][i]).reshape(-1, 2)
        rings = np.arange(len(pd)) + 0.04 * (i - 1)
        ax.errorbar(rings, pd, yerr=[pd - ci[:, 0], ci[:, 1] - pd], marker="o", capsize=3,
                    label=f"level {lv}: {doc['height_m'][i]:g} m, {2 * doc['view_radius'][i] + 1}^2 view, "
                          f"false alarms {doc['false_alarm_per_cell'][i]:.4f}/cell")
    cfg = doc["provenance"]["config"]
    ax.set_xlabel("ring (Chebyshev distance from the nadir cell, cells)")
    ax.set_ylabel("p_d (95 % Clopper-Pearson)")
    ax.set_xticks(range(max(len(p) for p in doc["p_detect"])))
    ax.set_ylim(min(0.0, ax.get_ylim()[0]) if min(min(p) for p in doc["p_detect"]) < 0.5 else 0.5, 1.02)
    ax.set_title(f"detector on the SITL camera ({cfg['camera_px']} px), {doc['frames']} frames, seed {cfg['seed']}",
                 fontsize=9)
    ax.grid(True, color="0.85")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    with atomic_open(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)
