"""Random masked fields from seeds, for training and evaluation: four classes of shape, each
with exactly a given number of searchable cells.

- convex: a convex polygon (5 to 8 vertices on a random ellipse) at a random rotation;
- L: two rotated rectangles sharing a corner (an L-shaped paddock);
- holes: a rotated rectangle with 1 to 3 round holes (a pond, a barn);
- strips: a thin band, 2.5 to 4 cells wide, at a random angle (a hedge-lined strip).

Each at a random angle to the grid (rotated, the default: edges become staircases), or laid
along it (rotated=False: the polygon's minimum-area rectangle, or its arms, along the grid's
axes, which is how `uavsearch field` lays a grid over a real field by default).

How: each shape is a continuous score over the plane, positive inside (the distance to the
nearest edge for a convex polygon; the max of two for a union, the min with the distance to
each hole for holes). The `area` cells of largest score are searchable: a level set of the
score, so the shape is the class's shape at exactly that area. A draw whose cells are not
4-connected (a hole cutting the field, a band rasterised too thin) is drawn again from the
next sub-seed. The field is then cropped to its bounding box; a batch of fields is padded
with masked cells to the batch's largest box (top-left aligned), so one GridConfig holds all.
"""

from __future__ import annotations

import numpy as np

MASK_CLASSES: tuple[str, ...] = ("convex", "L", "holes", "strips")
_TRIES = 50


def _poly_score(px: np.ndarray, py: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """Signed distance to the edges of a counter-clockwise convex polygon, min over edges
    (positive inside): its level sets are the polygon grown or shrunk."""
    a = verts
    b = np.roll(verts, -1, axis=0)
    e = b - a
    nrm = np.stack([-e[:, 1], e[:, 0]], axis=1) / np.linalg.norm(e, axis=1, keepdims=True)  # inward (ccw)
    s = (px[..., None] - a[:, 0]) * nrm[:, 0] + (py[..., None] - a[:, 1]) * nrm[:, 1]
    return s.min(axis=-1)


def _rect(cx: float, cy: float, length: float, width: float, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    u, v = np.array([c, s]) * length / 2, np.array([-s, c]) * width / 2
    ctr = np.array([cx, cy])
    return np.stack([ctr - u - v, ctr + u - v, ctr + u + v, ctr - u + v])


def _ccw(verts: np.ndarray) -> np.ndarray:
    area = np.sum(verts[:, 0] * np.roll(verts[:, 1], -1) - np.roll(verts[:, 0], -1) * verts[:, 1])
    return verts if area > 0 else verts[::-1]


def _align(verts: np.ndarray) -> np.ndarray:
    """A convex polygon turned so that its minimum-area bounding rectangle is axis-aligned (the
    heading `uavsearch field` lays its grid at by default; sim.field.default_heading)."""
    e = np.roll(verts, -1, axis=0) - verts
    best, turn = np.inf, 0.0
    for a in np.arctan2(e[:, 1], e[:, 0]):
        c, s = np.cos(-a), np.sin(-a)
        r = verts @ np.array([[c, s], [-s, c]])
        area = np.ptp(r[:, 0]) * np.ptp(r[:, 1])
        if area < best - 1e-12:
            best, turn = area, -a
    c, s = np.cos(turn), np.sin(turn)
    return verts @ np.array([[c, s], [-s, c]])


def _score(kind: str, area: int, rng: np.random.Generator, px: np.ndarray, py: np.ndarray,
           rotated: bool = True) -> np.ndarray:
    """The class's score on the points (px, py), its shape scaled to about `area` cells about
    the origin (the exact area is set by ranking). rotated=False: the shape's own axes along
    the grid's (a quarter turn at random), as `uavsearch field` lays a grid along a field."""
    angle = rng.uniform(0.0, np.pi)
    if not rotated:
        angle = float(np.floor(angle / (np.pi / 2))) * (np.pi / 2)
    if kind == "convex":
        k = int(rng.integers(5, 9))
        t = (np.arange(k) + rng.uniform(-0.3, 0.3, size=k)) * (2 * np.pi / k)
        aspect = rng.uniform(1.0, 2.0)
        ax, ay = np.sqrt(aspect), 1.0 / np.sqrt(aspect)
        pts = np.stack([ax * np.cos(t), ay * np.sin(t)], axis=1)
        c, s = np.cos(angle), np.sin(angle)
        verts = _ccw(pts @ np.array([[c, s], [-s, c]]))
        if not rotated:
            verts = _ccw(_align(verts))
        poly_area = 0.5 * abs(np.sum(verts[:, 0] * np.roll(verts[:, 1], -1) - np.roll(verts[:, 0], -1) * verts[:, 1]))
        return _poly_score(px, py, verts * np.sqrt(area / poly_area))
    if kind == "L":
        # arms of length L and width W (W < L): area = 2 L W - W^2
        ratio = rng.uniform(0.35, 0.6)  # W / L
        arm = np.sqrt(area / (2 * ratio - ratio ** 2))
        wid = ratio * arm
        c, s = np.cos(angle), np.sin(angle)
        u, v = np.array([c, s]), np.array([-s, c])
        r1 = _rect(*(u * arm / 2 + v * wid / 2), arm, wid, angle)
        r2 = _rect(*(u * wid / 2 + v * arm / 2), arm, wid, angle + np.pi / 2)
        return np.maximum(_poly_score(px, py, _ccw(r1)), _poly_score(px, py, _ccw(r2)))
    if kind == "holes":
        k = int(rng.integers(1, 4))
        radii = rng.uniform(0.6, 1.6, size=k) * np.sqrt(area) / 8
        hole_area = float(np.sum(np.pi * radii ** 2))
        aspect = rng.uniform(1.0, 1.8)
        full = area + hole_area
        length, width = np.sqrt(full * aspect), np.sqrt(full / aspect)
        score = _poly_score(px, py, _ccw(_rect(0.0, 0.0, length, width, angle)))
        c, s = np.cos(angle), np.sin(angle)
        for r in radii:
            a, b = rng.uniform(-0.3, 0.3) * length, rng.uniform(-0.3, 0.3) * width
            hx, hy = a * c - b * s, a * s + b * c
            score = np.minimum(score, np.hypot(px - hx, py - hy) - r)
        return score
    if kind == "strips":
        width = rng.uniform(2.5, 4.0)
        return _poly_score(px, py, _ccw(_rect(0.0, 0.0, area / width, width, angle)))
    raise ValueError(f"mask class must be one of {MASK_CLASSES} (got {kind!r})")


def _connected(mask: np.ndarray) -> bool:
    from .masks import UNREACHABLE, distance_fields

    ys, xs = np.nonzero(mask)
    d = distance_fields(mask[None], np.array([[xs[0], ys[0]]]))[0]
    return bool(np.all(d[mask] < UNREACHABLE))


def random_mask(kind: str, area: int, seed: int, rotated: bool = True) -> np.ndarray:
    """One field of the class with exactly `area` searchable, 4-connected cells, cropped to
    its bounding box: (h, w) bool, True = searchable. The same seed gives the same field.
    rotated: at a random angle to the grid (its edges staircases); False: laid along the
    grid, as `uavsearch field` lays the grid along a field's minimum-area rectangle."""
    if kind not in MASK_CLASSES:
        raise ValueError(f"mask class must be one of {MASK_CLASSES} (got {kind!r})")
    if area < 4:
        raise ValueError(f"a random field needs at least 4 searchable cells (got {area})")
    for attempt in range(_TRIES):
        rng = np.random.default_rng([seed, 0x3A5C, attempt])
        half = int(np.ceil(area / 5.0 if kind == "strips" else 2.0 * np.sqrt(area))) + 3
        coords = np.arange(-half, half + 1) + rng.uniform(-0.5, 0.5, size=2)[:, None]
        px, py = np.meshgrid(coords[0], coords[1], indexing="xy")
        score = _score(kind, area, rng, px, py, rotated) + rng.random(px.shape) * 1e-9  # ties at random
        keep = np.zeros(score.size, bool)
        keep[np.argsort(-score.reshape(-1), kind="stable")[:area]] = True
        m = keep.reshape(score.shape)
        ys, xs = np.nonzero(m)
        if ys.min() == 0 or xs.min() == 0 or ys.max() == m.shape[0] - 1 or xs.max() == m.shape[1] - 1:
            continue  # the window cut the shape (never seen: it is sized to hold it)
        m = m[ys.min(): ys.max() + 1, xs.min(): xs.max() + 1]
        if m.shape[0] >= 2 and m.shape[1] >= 2 and _connected(m):
            return m
    raise RuntimeError(f"no connected {kind!r} field of {area} cells in {_TRIES} draws from seed {seed}")


def random_masks(kind: str, area: int, n: int, seed: int, rotated: bool = True) -> np.ndarray:
    """n fields of the class (field i from seed (seed, i)), padded with masked cells to the
    largest bounding box: (n, h, w) bool."""
    if n < 1:
        raise ValueError(f"need at least one field (got {n})")
    fields = [random_mask(kind, area, int(np.random.SeedSequence([seed, i]).generate_state(1)[0]), rotated)
              for i in range(n)]
    h = max(f.shape[0] for f in fields)
    w = max(f.shape[1] for f in fields)
    out = np.zeros((n, h, w), bool)
    for i, f in enumerate(fields):
        out[i, : f.shape[0], : f.shape[1]] = f
    return out
