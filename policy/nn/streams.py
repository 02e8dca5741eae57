"""The two streams of Fig. 1 and their integration, in two sizes.

`paper` follows the authors' layer sizes (TFLearn, 'same' padding): an AlexNet-like visual
stream ending in two dense 4096 tanh layers, a map stream of one conv 12 + dense 1024 tanh, and
a linear head over the 5120 concatenated features. `small` is ours: the 3x3 view needs no
AlexNet, and the map's information is where the agent is and what it has visited, which a
couple of 3x3 convolutions over the whole map capture; it trains ~50x faster on a CPU.
"""

from __future__ import annotations

import torch
from torch import nn


def _flat_size(module: nn.Module, shape: tuple[int, int, int]) -> int:
    with torch.no_grad():
        return int(module(torch.zeros(1, *shape)).flatten(1).shape[1])


def _lrn() -> nn.Module:
    return nn.LocalResponseNorm(size=5, alpha=1e-4, beta=0.75, k=2.0)


def _pool() -> nn.Module:
    return nn.MaxPool2d(3, stride=2, padding=1, ceil_mode=True)


def paper_visual(shape: tuple[int, int, int]) -> tuple[nn.Module, int]:
    c = shape[0]
    conv = nn.Sequential(
        nn.Conv2d(c, 96, 11, stride=4, padding=5), nn.ReLU(), _pool(), _lrn(),
        nn.Conv2d(96, 256, 5, padding=2), nn.ReLU(), _pool(), _lrn(),
        nn.Conv2d(256, 384, 3, padding=1), nn.ReLU(),
        nn.Conv2d(384, 384, 3, padding=1), nn.ReLU(),
        nn.Conv2d(384, 256, 3, padding=1), nn.ReLU(), _pool(), _lrn(),
    )
    n = _flat_size(conv, shape)
    return nn.Sequential(
        conv, nn.Flatten(),
        nn.Linear(n, 4096), nn.Tanh(), nn.Dropout(0.5),
        nn.Linear(4096, 4096), nn.Tanh(), nn.Dropout(0.5),
    ), 4096


def paper_map(shape: tuple[int, int, int]) -> tuple[nn.Module, int]:
    conv = nn.Sequential(nn.Conv2d(shape[0], 12, 3, padding=1), nn.ReLU(), _pool(), _lrn())
    n = _flat_size(conv, shape)
    return nn.Sequential(conv, nn.Flatten(), nn.Linear(n, 1024), nn.Tanh()), 1024


def small_visual(shape: tuple[int, int, int]) -> tuple[nn.Module, int]:
    c, h, w = shape
    if h * w <= 25:  # the grid view: every pixel is a cell
        conv = nn.Sequential(nn.Conv2d(c, 32, 3, padding=1), nn.ReLU())
    else:  # a rendered frame
        conv = nn.Sequential(
            nn.Conv2d(c, 16, 5, stride=2, padding=2), nn.ReLU(),
            nn.Conv2d(16, 32, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(32, 32, 3, stride=2, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool2d(4),
        )
    n = _flat_size(conv, shape)
    return nn.Sequential(conv, nn.Flatten(), nn.Linear(n, 128), nn.ReLU()), 128


def small_map(shape: tuple[int, int, int]) -> tuple[nn.Module, int]:
    conv = nn.Sequential(
        nn.Conv2d(shape[0], 16, 3, padding=1), nn.ReLU(),
        nn.Conv2d(16, 16, 3, padding=1), nn.ReLU(),
    )
    n = _flat_size(conv, shape)
    return nn.Sequential(conv, nn.Flatten(), nn.Linear(n, 256), nn.ReLU()), 256


STREAMS = {"paper": (paper_visual, paper_map), "small": (small_visual, small_map)}


def init_weights(module: nn.Module) -> None:
    """The paper initialises from a truncated normal; biases start at zero."""
    for m in module.modules():
        if isinstance(m, nn.Conv2d | nn.Linear):
            fan_in = m.weight[0].numel()
            nn.init.trunc_normal_(m.weight, std=(2.0 / fan_in) ** 0.5, a=-2 * (2.0 / fan_in) ** 0.5,
                                  b=2 * (2.0 / fan_in) ** 0.5)
            nn.init.zeros_(m.bias)
