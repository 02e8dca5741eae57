"""Where `belief`'s extra moves go on masked fields (issue 28): per class, the moves split by
what they did, against the rectangle of the same searchable area.

Each move of an episode is one of:
- tour: after every target is sighted (the exact Held-Karp tour; nothing left to learn);
- new: before that, its view showed at least one never-seen searchable cell;
- dead: before that, it showed nothing new (travel to a goal over seen ground: a return to
  left-over cells, or a crossing).
Also: cover, the 3 x 3 views a greedy set cover needs to show the whole field (what the view
alone costs, no travel; the oracle needs no view, so a field that needs more views per oracle
move than the rectangle costs any view-based search more, whatever it plans). And: revisits (moves onto a cell the agent stood on before, search phase), and the
left-over cells: cells first seen more than `late` moves after the agent first came within
two cells of them (it passed them by and came back).

    PYTHONPATH=. python benchmarks/masked_belief_moves.py [FIELDS (300)] [SEED (1)] [k=v planner params...]

The planner parameters (policy.planner.PlannerParams, e.g. pocket=0 spread=0 mask_travel_offset=0.5
for the planner before issue 28's masked-field terms) apply to the masked fields; the rectangle
always runs the defaults (no mask: the terms do not apply). Tune on seeds other than 0 (the
committed quality run's seed).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from policy.base import observe
from policy.groundtruth import optimal_lengths
from policy.planner import BeliefPlanner, PlannerParams
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes
from sim.gridworld.mask_fields import MASK_CLASSES, random_masks


def _seen(visited: np.ndarray) -> np.ndarray:
    """(n, h, w) bool: cells inside the 3 x 3 view of some visited cell."""
    out = visited.copy()
    out[:, 1:] |= visited[:, :-1]
    out[:, :-1] |= visited[:, 1:]
    o2 = out.copy()
    o2[:, :, 1:] |= out[:, :, :-1]
    o2[:, :, :-1] |= out[:, :, 1:]
    return o2


def _near(visited: np.ndarray) -> np.ndarray:
    """cells within Chebyshev distance 2 of a visited cell."""
    return _seen(_seen(visited))


def view_cover(mask: np.ndarray) -> float:
    """Mean number of 3 x 3 view positions a greedy set cover needs to show every searchable
    cell of each field (n, h, w): the coverage cost of the view alone, no travel counted
    (16 on the 10 x 10 rectangle, its optimum)."""
    from policy.planner.planner import _window

    n, h, w = mask.shape
    left = mask.astype(np.float64)
    k = np.zeros(n, np.int64)
    rows = np.arange(n)
    while left.any():
        s = _window(left, 1)
        s[~mask] = -1.0
        idx = s.reshape(n, -1).argmax(axis=1)
        k += left.reshape(n, -1).any(axis=1)
        y, x = idx // w, idx % w
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                ok = (y + dy >= 0) & (y + dy < h) & (x + dx >= 0) & (x + dx < w)
                left[rows[ok], (y + dy)[ok], (x + dx)[ok]] = 0.0
    return float(k.mean())


def run(mask: np.ndarray | None, w: int, h: int, fields: int, seed: int, params: PlannerParams,
        late: int = 6) -> dict[str, float]:
    cfg = GridConfig(width=w, height=h, n_targets=5)
    ep = sample_episodes(cfg, fields, seed) if mask is None else sample_episodes(cfg, fields, seed, mask)
    pol = BeliefPlanner(params=params)
    pol.reset(cfg, fields, seed)
    world = BatchGridWorld(ep, seed)
    on = np.ones((fields, h, w), bool) if mask is None else np.broadcast_to(mask, (fields, h, w))
    seen = _seen(world.visited) & on
    near_t = np.where(_near(world.visited), 0, -1)
    seen_t = np.where(seen, 0, -1)
    c = {"tour": 0, "new": 0, "dead": 0, "revisit": 0}
    t = 0
    while not world.done.all():
        obs = observe(world)
        active = ~world.done
        touring = pol.in_tour.copy() if t > 0 else np.zeros(fields, bool)
        a = pol.act(obs)
        touring |= pol.in_tour & (pol.tour_len > 0)
        before = world.visited.copy()
        world.step(a)
        t += 1
        rows = np.arange(fields)
        x, y = world.agent[:, 0], world.agent[:, 1]
        revisit = before[rows, y, x]
        s2 = _seen(world.visited) & on
        fresh = (s2 & ~seen).reshape(fields, -1).any(axis=1)
        seen_t[s2 & ~seen] = t
        n2 = _near(world.visited)
        near_t[n2 & (near_t < 0)] = t
        seen = s2
        search = active & ~touring
        c["tour"] += int((active & touring).sum())
        c["new"] += int((search & fresh).sum())
        c["dead"] += int((search & ~fresh).sum())
        c["revisit"] += int((search & revisit).sum())
    ok = seen_t >= 0
    left = ((seen_t - near_t) > late) & ok & on
    out = {k: v / fields for k, v in c.items()}
    out["moves"] = float(world.t.mean())
    out["ratio"] = out["moves"] / float(optimal_lengths(ep).mean())
    out["leftover"] = float(left.sum() / fields)
    out["seen"] = float((ok & on).sum() / fields)
    out["cover"] = view_cover(np.ascontiguousarray(on))
    out["oracle"] = float(optimal_lengths(ep).mean())
    return out


def main() -> None:
    args = sys.argv[1:]
    nums = [a for a in args if "=" not in a]
    fields = int(nums[0]) if nums else 300
    seed = int(nums[1]) if len(nums) > 1 else 1
    kw = {k: float(v) for k, v in (a.split("=") for a in args if "=" in a)}
    params = PlannerParams(**kw)
    classes = MASK_CLASSES
    t0 = time.time()
    rows = [("rectangle", run(None, 10, 10, fields, seed, PlannerParams()))]  # no mask: the defaults
    for rot in (False, True):
        for kind in classes:
            m = random_masks(kind, 100, fields, seed, rotated=rot)
            rows.append((f"{kind}, {'rotated' if rot else 'aligned'}", run(m, m.shape[2], m.shape[1], fields, seed, params)))
    print(f"{fields} fields, seed {seed}, {kw or 'defaults'}; {time.time() - t0:.0f} s")
    rect = rows[0][1]["ratio"]
    print(f"{'field':18s} {'ratio':>6s} {'vs rect':>7s} {'moves':>6s} {'new':>6s} {'dead':>6s} {'tour':>6s} {'revisit':>7s} {'leftover':>8s} {'seen':>6s} {'cover':>6s} {'cover/oracle vs rect':>20s}")
    for name, r in rows:
        print(f"{name:18s} {r['ratio']:6.3f} {r['ratio'] / rect - 1:+7.1%} {r['moves']:6.1f} {r['new']:6.1f} {r['dead']:6.1f} {r['tour']:6.1f} {r['revisit']:7.1f} "
              f"{r['leftover']:8.1f} {r['seen']:6.1f} {r['cover']:6.1f} "
              f"{r['cover'] / r['oracle'] / (rows[0][1]['cover'] / rows[0][1]['oracle']) - 1:+20.1%}")


if __name__ == "__main__":
    main()
