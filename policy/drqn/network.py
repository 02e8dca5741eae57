"""The DRQN (Hausknecht & Stone): a DQN conv stack whose last layer spans the whole feature
map, an LSTM in place of the first fully connected layer, and dueling heads.

The dueling heads follow the widely used reference implementation the authors' numbers match
(the LSTM output split into two halves, one for the advantages, one for the value;
Q = V + A - mean(A)). With the 84 px input the last conv is 512 7x7/1; with the 42 px CI
option it spans the 1x1 map left there, so the layer count and widths stay the same.
"""

from __future__ import annotations

import torch
from torch import nn

from .config import DrqnConfig, conv_output_size

Hidden = tuple[torch.Tensor, torch.Tensor]


class DrqnNet(nn.Module):
    def __init__(self, cfg: DrqnConfig) -> None:
        super().__init__()
        self.cfg = cfg
        layers: list[nn.Module] = []
        c = 3
        for out, k, s in cfg.conv:
            layers += [nn.Conv2d(c, out, k, s), nn.ReLU()]
            c = out
        span = conv_output_size(cfg.input_size, cfg.conv)
        layers += [nn.Conv2d(c, cfg.hidden, span, 1), nn.ReLU(), nn.Flatten()]
        self.features = nn.Sequential(*layers)
        self.lstm = nn.LSTM(cfg.hidden, cfg.hidden, batch_first=True)
        half = cfg.hidden // 2
        self.advantage = nn.Linear(half, cfg.n_actions)
        self.value = nn.Linear(half, 1)

    def initial(self, batch: int) -> Hidden:
        z = torch.zeros(1, batch, self.cfg.hidden)
        return z, z.clone()

    def forward(self, x: torch.Tensor, hidden: Hidden | None = None) -> tuple[torch.Tensor, Hidden]:
        """x (B, T, 3, S, S) float -> Q (B, T, A), (h, c) each (1, B, hidden)."""
        if x.ndim != 5 or x.shape[2:] != (3, self.cfg.input_size, self.cfg.input_size):
            raise ValueError(
                f"expected input (B, T, 3, {self.cfg.input_size}, {self.cfg.input_size}), got {tuple(x.shape)}"
            )
        b, t = x.shape[:2]
        f = self.features(x.reshape(b * t, *x.shape[2:])).reshape(b, t, -1)
        if hidden is None:
            hidden = self.initial(b)
        out, hidden = self.lstm(f, hidden)
        a_stream, v_stream = out.split(self.cfg.hidden // 2, dim=-1)
        a = self.advantage(a_stream)
        q = self.value(v_stream) + a - a.mean(dim=-1, keepdim=True)
        return q, hidden
