"""The search network: small and fully convolutional over the agent-centred belief, so it
decides on any field size in well under a millisecond on one CPU thread.

Two views of the same features reach the head: the first layer's features in a small window
around the agent as they are (what is adjacent: a sighted target one step away), and the
max and mean over the whole field of two strided layers (where the unseen, likely cells lie,
in which direction and how far: the offset planes make that position-aware). The same class
is the critic in PPO, built with `privileged_channels` for the truth it alone may see.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .config import SearchNetConfig
from .encode import EXTRA_PLANES


class SearchNet(nn.Module):
    def __init__(self, cfg: SearchNetConfig) -> None:
        super().__init__()
        self.cfg = cfg
        c = cfg.field_planes + EXTRA_PLANES
        self.conv1 = nn.Conv2d(c, cfg.conv1, 3, padding=1)
        self.conv2 = nn.Conv2d(cfg.conv1, cfg.conv2, 3, stride=2, padding=1)
        self.conv3 = nn.Conv2d(cfg.conv2, cfg.conv2, 3, stride=2, padding=1)
        self.local = nn.Linear(cfg.conv1 * cfg.local * cfg.local, cfg.hidden)
        self.glob = nn.Linear(4 * cfg.conv2, cfg.hidden)
        self.mix = nn.Linear(cfg.hidden, cfg.hidden)
        self.pi = nn.Linear(cfg.hidden, cfg.n_actions)
        self.v = nn.Linear(cfg.hidden, 1)

    def features(self, x: torch.Tensor) -> torch.Tensor:
        """x: egocentric input (B, C, 2h - 1, 2w - 1) with the agent at the centre."""
        f1 = F.relu(self.conv1(x))
        k = self.cfg.local // 2
        h, w = x.shape[-2] // 2, x.shape[-1] // 2
        f1p = F.pad(f1, (k, k, k, k))
        loc = f1p[:, :, h: h + 2 * k + 1, w: w + 2 * k + 1].flatten(1)
        f2 = F.relu(self.conv2(f1))
        f3 = F.relu(self.conv3(f2))
        g = torch.cat([f2.amax(dim=(2, 3)), f2.mean(dim=(2, 3)), f3.amax(dim=(2, 3)), f3.mean(dim=(2, 3))], dim=1)
        z = F.relu(self.local(loc) + self.glob(g))
        return F.relu(self.mix(z)) + z

    def forward(self, x: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
        """Action logits (B, n_actions); actions where mask is False get -inf-like logits."""
        logits = self.pi(self.features(x))
        if mask is not None:
            logits = logits.masked_fill(~mask, -1e9)
        return logits

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.v(self.features(x)).squeeze(1)
