"""Which fields searchnet trains and validates on: the whole rectangle (today's), one fixed
masked field (a field file's searchable cells, `uavsearch train --field FILE`), or random
masked fields of the classes in sim.gridworld.mask_fields (issue 28).

Why a spec and not masks: a DAgger task is sent to another process with its seed and draws
its own fields from it, so the data set is the same on any number of workers. Random fields
of one task share a grid (random_masks pads them to the batch's largest bounding box, top-left
aligned), and tasks' grids differ; merge() pads the planes to the largest, zero there (off the
field: the on-map plane, which carries the mask, is 0), which is what an evaluation on a batch of
padded fields shows the network too.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from sim.gridworld import GridConfig


@dataclass(frozen=True)
class FieldSpec:
    #: a fixed field: rows of 0/1 (searchable), the grid's height x width; None: random fields
    mask: tuple[tuple[int, ...], ...] | None = None
    #: random fields: the classes drawn from, episode by episode in turn (sim.gridworld.mask_fields)
    classes: tuple[str, ...] = ()
    #: random fields: searchable cells per field
    area: int = 100
    rotated: bool = True

    def __post_init__(self) -> None:
        from sim.gridworld.mask_fields import MASK_CLASSES

        if (self.mask is None) == (not self.classes):
            raise ValueError("FieldSpec: give either a fixed mask or random field classes (not both, not neither)")
        bad = [c for c in self.classes if c not in MASK_CLASSES]
        if bad:
            raise ValueError(f"FieldSpec: unknown mask class(es) {bad}; known: {list(MASK_CLASSES)}")
        if self.classes and self.area < 4:
            raise ValueError(f"FieldSpec.area must be >= 4 searchable cells (got {self.area})")
        if self.mask is not None:
            m = np.asarray(self.mask)
            if m.ndim != 2 or m.sum() < 2:
                raise ValueError(f"FieldSpec.mask must be 2-D rows with >= 2 searchable cells (got shape {m.shape})")

    @classmethod
    def fixed(cls, mask: np.ndarray) -> FieldSpec:
        return cls(mask=tuple(tuple(int(v) for v in row) for row in np.asarray(mask, bool)))

    def draw(self, grid: GridConfig, n: int, seed: int) -> tuple[GridConfig, np.ndarray]:
        """(the grid these n episodes run on, their masks (h, w) or (n, h, w)) for a task's seed."""
        if self.mask is not None:
            m = np.asarray(self.mask, bool)
            if m.shape != (grid.height, grid.width):
                raise ValueError(f"the field is {m.shape[1]} x {m.shape[0]} cells, the grid "
                                 f"{grid.width} x {grid.height}")
            return grid, m
        from sim.gridworld.mask_fields import random_mask, random_masks

        if len(self.classes) == 1:  # one class: random_masks' fields, as the masked evaluation draws them
            masks = random_masks(self.classes[0], self.area, n, seed, rotated=self.rotated)
        else:  # episode i of the class i mod k, from random_masks' per-field seeds; padded alike
            fields = [random_mask(self.classes[i % len(self.classes)], self.area,
                                  int(np.random.SeedSequence([seed, i]).generate_state(1)[0]), self.rotated)
                      for i in range(n)]
            masks = np.zeros((n, max(f.shape[0] for f in fields), max(f.shape[1] for f in fields)), bool)
            for i, f in enumerate(fields):
                masks[i, : f.shape[0], : f.shape[1]] = f
        return dataclasses.replace(grid, width=masks.shape[2], height=masks.shape[1]), masks

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict | None) -> FieldSpec | None:
        if d is None:
            return None
        m = d.get("mask")
        return cls(mask=None if m is None else tuple(tuple(r) for r in m), classes=tuple(d.get("classes", ())),
                   area=int(d.get("area", 100)), rotated=bool(d.get("rotated", True)))
