"""The probabilistic visitation map: the paper's future work (Section VII).

With GPS the UAV never knows its cell for sure. Each decision step spreads the visit over the
cells the position posterior covers: P(cell visited) = 1 - prod_steps (1 - P(in cell at step)).
The map the network reads is the expectation of the crisp encoding (visited 1, agent 10, met
target 5), so a network trained on crisp maps consumes it unchanged, and a certain position
reproduces the crisp map exactly.
"""

from __future__ import annotations

import numpy as np

from policy.belief.gps import cell_probabilities_xy
from sim.gridworld import DEFAULT_CELL_M, ned_to_cell
from sim.gridworld.observations import AGENT_VALUE, MET_VALUE, VISITED_VALUE

#: the most sub-samples per cell side `cell_probabilities` integrates a correlated Gaussian on
#: (a 26 x 26 field: 832 x 832 points)
MAX_SUBSAMPLES = 32
#: the spatiotemporal trail written at the current cell (GridConfig.trail_value's default)
TRAIL_VALUE = 50.0


def cell_probabilities(
    mean_ne: np.ndarray, cov_ne: np.ndarray, width: int, height: int, cell_m: float = DEFAULT_CELL_M
) -> np.ndarray:
    """(h, w) probability mass of a 2-D Gaussian position posterior in each grid cell.

    Cells are squares of side cell_m centred on their grid point. The covariance is taken
    along its own principal axes only when they align with the grid; otherwise the mass of
    each cell is integrated on a sub-grid, which is exact to ~1e-3 for sigma >= 0.1 cell.
    """
    mu = ned_to_cell(np.asarray(mean_ne, dtype=float)[:2], cell_m)  # (x, y) fractional
    j = np.array([[0.0, 1.0], [-1.0, 0.0]]) / cell_m  # (n, e) -> (x, y)
    cov = j @ np.asarray(cov_ne, dtype=float)[:2, :2] @ j.T
    if not np.all(np.isfinite(cov)) or np.linalg.eigvalsh(cov).min() < -1e-12:
        raise ValueError("covariance must be finite and positive semi-definite")
    sx, sy = np.sqrt(max(cov[0, 0], 1e-12)), np.sqrt(max(cov[1, 1], 1e-12))
    rho = cov[0, 1] / (sx * sy)
    if abs(rho) < 1e-3:  # the grid-world evaluation's maths, policy.belief.gps
        return cell_probabilities_xy(mu[None], np.array([[sx, sy]]), width, height, fold=False)[0]
    # sub-samples per cell side: 8 resolves a Gaussian down to 0.1 cell sd (~1e-3); a thinner
    # one across a slanted line (a polygon edge's registration: ~0.05 m across the edge) needs
    # the spacing kept near 1.25 sd, else the samples on its ridge summed past 1 (farm flight
    # seed 3: 1.03, and the map refused it). Thinner still than the finest spacing, the mass
    # is scaled back to at most 1 (cells' shares are then good to the sampling's resolution)
    sd_min = float(np.sqrt(max(float(np.linalg.eigvalsh(cov).min()), 1e-12)))
    k = 8 if sd_min >= 0.1 else min(int(np.ceil(0.8 / sd_min)), MAX_SUBSAMPLES)
    off = (np.arange(k) + 0.5) / k - 0.5
    gx = (np.arange(width)[:, None] + off).ravel()
    gy = (np.arange(height)[:, None] + off).ravel()
    dx, dy = np.meshgrid(gx - mu[0], gy - mu[1], indexing="xy")
    inv = np.linalg.inv(cov)
    q = inv[0, 0] * dx**2 + 2 * inv[0, 1] * dx * dy + inv[1, 1] * dy**2
    pdf = np.exp(-0.5 * q) / (2 * np.pi * np.sqrt(np.linalg.det(cov))) / k**2
    p = pdf.reshape(height, k, width, k).sum(axis=(1, 3))
    total = float(p.sum())
    return p / total if total > 1.0 else p


class ProbabilisticVisitationMap:
    def __init__(self, width: int, height: int, cell_m: float = DEFAULT_CELL_M) -> None:
        if width < 1 or height < 1 or cell_m <= 0:
            raise ValueError("width, height and cell_m must be positive")
        self.width, self.height, self.cell_m = width, height, cell_m
        self.visited = np.zeros((height, width))
        self.met = np.zeros((height, width))
        self.current = np.zeros((height, width))
        # the spatiotemporal map's two decaying channels (trail, recoveries), in expectation
        self.trail = np.zeros((height, width))
        self.recovered = np.zeros((height, width))

    def visit(self, mean_ne: np.ndarray, cov_ne: np.ndarray) -> np.ndarray:
        """One decision step at the posterior (mean, cov). Returns P(in cell) now."""
        return self.visit_cells(cell_probabilities(mean_ne, cov_ne, self.width, self.height, self.cell_m))

    def visit_cells(self, p: np.ndarray) -> np.ndarray:
        """One decision step with P(in cell) given per cell ((h, w), e.g. a Gaussian sum's
        `cell_probabilities` weighed by its components). Returns p."""
        p = np.asarray(p, dtype=float)
        if p.shape != self.visited.shape or not np.all(np.isfinite(p)) or p.min() < 0 or p.sum() > 1.01:
            raise ValueError(f"cell probabilities must be a ({self.height}, {self.width}) array of "
                             f"non-negative numbers summing to at most 1 (got shape {p.shape}, sum {p.sum():.3g})")
        self.visited = 1.0 - (1.0 - self.visited) * (1.0 - p)
        self.current = p
        # as the grid world's spatiotemporal map: every value decays by 1 a step, the current
        # cell is written TRAIL_VALUE (here each cell in proportion to P(in cell))
        self.trail = np.maximum(self.trail - 1.0, 0.0)
        self.trail = (1.0 - p) * self.trail + p * TRAIL_VALUE
        self.recovered = np.maximum(self.recovered - 1.0, 0.0)
        return p

    def mark_target(self) -> None:
        """A target was detected under the UAV: spread the mark like the visit."""
        self.met = 1.0 - (1.0 - self.met) * (1.0 - self.current)
        self.recovered = (1.0 - self.current) * self.recovered + self.current * TRAIL_VALUE

    def most_likely_cell(self) -> tuple[int, int]:
        y, x = np.unravel_index(int(np.argmax(self.current)), self.current.shape)
        return int(x), int(y)

    def policy_map(self, variant: str) -> np.ndarray:
        """The map M the policy was trained on (GridConfig.map_variant), in expectation."""
        if variant == "spatiotemporal":
            return np.stack([self.trail, self.recovered]).astype(np.float32)
        if variant not in ("spatial", "memory"):
            raise ValueError(f"unknown map variant {variant!r}")
        return self.expected_map(memory=variant == "memory")

    def expected_map(self, memory: bool = False) -> np.ndarray:
        """(1, h, w) float32: the expectation of the crisp spatial (or +M) encoding."""
        base = self.visited * VISITED_VALUE
        if memory:
            base = base + self.met * (MET_VALUE - VISITED_VALUE)
        m = (1.0 - self.current) * base + self.current * AGENT_VALUE
        return m[None].astype(np.float32)
