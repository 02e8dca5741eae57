"""The DRQN baseline's network and view (Hausknecht & Stone 2015, as the authors used it):
the 3x3 view drawn as an RGB image (white outside the map, found targets in another colour)
scaled to 84x84, three convolutions and a 512 one, an LSTM of 512, dueling value/advantage heads."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

WHITE, TARGET, FOUND, AGENT = (255, 255, 255), (255, 0, 0), (0, 0, 255), (0, 255, 0)


def drqn_view(views: np.ndarray, found_here: np.ndarray, size: int = 84) -> np.ndarray:
    """Grid views (n, 3, 3, 3) {target, off-map, agent} + which view cells hold a found target
    (n, 3, 3) -> (n, 3, size, size) uint8 images."""
    n = len(views)
    img = np.zeros((n, 3, 3, 3), dtype=np.uint8)  # (n, y, x, rgb)
    img[views[:, 1].astype(bool)] = WHITE
    tgt = views[:, 0].astype(bool)
    img[tgt & ~found_here] = TARGET
    img[tgt & found_here] = FOUND
    img[:, 1, 1] = AGENT
    scale = -(-size // 3)
    big = np.repeat(np.repeat(img, scale, axis=1), scale, axis=2)[:, :size, :size]
    return np.ascontiguousarray(big.transpose(0, 3, 1, 2))


class Drqn(nn.Module):
    def __init__(self, n_actions: int = 4, image: int = 84, hidden: int = 512) -> None:
        super().__init__()
        conv = nn.Sequential(
            nn.Conv2d(3, 32, 8, stride=4), nn.ReLU(),
            nn.Conv2d(32, 64, 4, stride=2), nn.ReLU(),
            nn.Conv2d(64, 64, 3, stride=1), nn.ReLU(),
        )
        with torch.no_grad():
            k = conv(torch.zeros(1, 3, image, image)).shape[-1]
        # the last conv spans what is left (7x7 at 84 px), giving one 512-d vector
        self.conv = nn.Sequential(conv, nn.Conv2d(64, hidden, k), nn.ReLU(), nn.Flatten())
        self.lstm = nn.LSTM(hidden, hidden, batch_first=True)
        self.value = nn.Linear(hidden, 1)
        self.advantage = nn.Linear(hidden, n_actions)
        self.hidden = hidden

    def forward(self, frames: torch.Tensor, state=None, index: torch.Tensor | None = None):
        """frames (B, T, 3, H, W) uint8 -> Q (B, T, A), new LSTM state. With `index` (B, T),
        `frames` holds only the distinct images (U, 3, H, W) and index says which one each step
        shows: the same function and gradients, with the convolutions run once per image."""
        if index is None:
            b, t = frames.shape[:2]
            frames, index = frames.reshape(b * t, *frames.shape[2:]), torch.arange(b * t).reshape(b, t)
        z = self.conv(frames.float() / 255.0)[index]
        out, state = self.lstm(z, state)
        adv = self.advantage(out)
        return self.value(out) + adv - adv.mean(dim=-1, keepdim=True), state
