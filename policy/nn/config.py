"""What a network is: enough to rebuild it from a checkpoint without the dataset at hand."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from .encode import map_scale_for, view_scale_for

MODELS = ("dualstream", "ssn")
ARCHS = ("small", "paper")


@dataclass(frozen=True)
class ModelConfig:
    model: str = "dualstream"  # dualstream | ssn
    arch: str = "small"  # small (our default) | paper (the authors' layer sizes)
    view_shape: tuple[int, int, int] = (3, 3, 3)  # (C, H, W) of I: the 3x3 grid view or a rendered frame
    map_shape: tuple[int, int, int] = (1, 10, 10)  # (C, h, w) of M
    n_actions: int = 4
    #: inputs are divided by these (grid views are 0/1, rendered frames 0..255; maps 10 or 50)
    view_scale: float = 1.0
    map_scale: float = 10.0

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {MODELS} (got {self.model!r})")
        if self.arch not in ARCHS:
            raise ValueError(f"arch must be one of {ARCHS} (got {self.arch!r})")
        if self.n_actions not in (4, 5):
            raise ValueError(f"n_actions must be 4 or 5 (got {self.n_actions})")
        if len(self.view_shape) != 3 or len(self.map_shape) != 3:
            raise ValueError("view_shape and map_shape are (C, H, W)")
        if self.view_scale <= 0 or self.map_scale <= 0:
            raise ValueError("scales must be > 0")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["view_shape"], d["map_shape"] = list(self.view_shape), list(self.map_shape)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> ModelConfig:
        d = dict(d)
        d["view_shape"], d["map_shape"] = tuple(d["view_shape"]), tuple(d["map_shape"])
        return cls(**d)

    @classmethod
    def for_data(cls, view_shape, map_shape, n_actions: int, rendered: bool, **kw) -> ModelConfig:
        """The config that fits a dataset: scales from what the inputs hold."""
        return cls(
            view_shape=tuple(view_shape),
            map_shape=tuple(map_shape),
            n_actions=n_actions,
            view_scale=view_scale_for(rendered),
            map_scale=map_scale_for(map_shape[0]),
            **kw,
        )
