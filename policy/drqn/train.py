"""DRQN training by reward in the grid world, as the paper's off-the-shelf baseline: double DQN,
soft target updates, an episode replay of 1000 episodes sampled as 4 sequences of 8 steps with
the first half of each sequence's loss masked (Lample & Chaplot's trick), epsilon 1 -> 0.1,
reward +1 per new target and nothing else, a wall bump leaves the agent in place."""

from __future__ import annotations

import copy
import io
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from provenance import atomic_write_bytes, git_revision
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

from ..nn.checkpoint import CheckpointError, read_torch_document
from .model import Drqn, drqn_view

FORMAT = "uavsearch-drqn/1"


@dataclass(frozen=True)
class DrqnConfig:
    image: int = 84
    episodes: int = 20_000
    envs: int = 16
    lr: float = 1e-4
    gamma: float = 0.99
    tau: float = 0.001
    target_every: int = 5
    buffer_episodes: int = 1000
    batch_seqs: int = 4
    seq_len: int = 8
    eps_start: float = 1.0
    eps_end: float = 0.1
    eps_anneal_steps: int = 10_000
    warmup_steps: int = 10_000
    test_epsilon: float = 0.01
    #: cap episode length while training (the test harness always uses t_e)
    train_max_steps: int = 300

    def __post_init__(self) -> None:
        if self.image < 36:
            raise ValueError("image must be >= 36 px for the DRQN's convolutions")
        if self.episodes < 1 or self.envs < 1 or self.seq_len < 2 or self.batch_seqs < 1:
            raise ValueError("episodes, envs, batch_seqs >= 1 and seq_len >= 2")


def found_in_view(views: np.ndarray, maps: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Which view cells hold a target the agent has already met (a target on a visited cell)."""
    n, _, h, w = maps.shape
    off = np.arange(-1, 2)
    ys = np.clip(pos[:, 1, None] + off, 0, h - 1)
    xs = np.clip(pos[:, 0, None] + off, 0, w - 1)
    visited = maps[np.arange(n)[:, None, None], 0, ys[:, :, None], xs[:, None, :]] > 0
    return views[:, 0].astype(bool) & visited


def save_drqn(path: Path, net: Drqn, cfg: DrqnConfig, grid: GridConfig, seed: int, **extra) -> Path:
    buf = io.BytesIO()
    torch.save({"format": FORMAT, "drqn_config": asdict(cfg), "grid_config": grid.to_dict(), "seed": seed,
                "git_revision": git_revision(), "state_dict": net.state_dict(), **extra}, buf)
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def load_drqn(path: str | Path) -> tuple[Drqn, dict]:
    doc = read_torch_document(path, FORMAT, ("drqn_config", "grid_config", "state_dict"))
    cfg = DrqnConfig(**doc["drqn_config"])
    net = Drqn(GridConfig.from_dict(doc["grid_config"]).n_actions, cfg.image)
    try:
        net.load_state_dict(doc["state_dict"])
    except RuntimeError as e:
        raise CheckpointError(f"{path}: weights do not fit the DRQN ({e})") from e
    return net.eval(), doc


class EpisodeReplay:
    """Whole episodes of compact observations (3x3 views + found flags), rendered on sampling."""

    def __init__(self, capacity: int, rng: np.random.Generator) -> None:
        self.capacity, self.rng, self.episodes = capacity, rng, []

    def add(self, views, found, actions, rewards) -> None:
        if len(actions) == 0:
            return
        self.episodes.append((np.asarray(views), np.asarray(found), np.asarray(actions), np.asarray(rewards, np.float32)))
        if len(self.episodes) > self.capacity:
            self.episodes.pop(0)

    def sample(self, n: int, length: int):
        """(views (n, L+1, 3,3,3), found (n, L+1, 3,3), actions (n, L), rewards (n, L), done (n, L), valid (n, L))."""
        out_v, out_f, out_a, out_r, out_d, out_m = [], [], [], [], [], []
        for i in self.rng.integers(0, len(self.episodes), n):
            v, f, a, r = self.episodes[i]
            t = len(a)
            s = int(self.rng.integers(0, max(1, t - length + 1)))
            e = min(s + length, t)
            pad = length - (e - s)
            # frame after the last action is not stored: that step's target is masked by done
            idx = np.minimum(np.r_[np.arange(s, e + 1), np.full(pad, e)], t - 1)
            out_v.append(v[idx])
            out_f.append(f[idx])
            out_a.append(np.r_[a[s:e], np.zeros(pad, a.dtype)])
            out_r.append(np.r_[r[s:e], np.zeros(pad, np.float32)])
            done = np.zeros(length, np.float32)
            if e == t:
                done[e - s - 1] = 1.0
            out_d.append(done)
            out_m.append(np.r_[np.ones(e - s), np.zeros(pad)].astype(np.float32))
        return tuple(map(np.stack, (out_v, out_f, out_a, out_r, out_d, out_m)))


def td_targets(q_next_online: torch.Tensor, q_next_target: torch.Tensor, rewards: torch.Tensor,
               done: torch.Tensor, gamma: float) -> torch.Tensor:
    """Double DQN: the online net picks the next action, the target net values it."""
    a_star = q_next_online.argmax(dim=-1, keepdim=True)
    return rewards + gamma * (1.0 - done) * q_next_target.gather(-1, a_star).squeeze(-1)


def train_drqn(cfg: DrqnConfig, grid: GridConfig, out: str | Path, seed: int = 0, progress: bool = True) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(seed)
    rng = np.random.default_rng([seed, 0xD2])
    net = Drqn(grid.n_actions, cfg.image)
    target = copy.deepcopy(net)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    replay = EpisodeReplay(cfg.buffer_episodes, rng)
    steps, updates, done_eps, rewards_log, losses = 0, 0, 0, [], []
    bar = tqdm(total=cfg.episodes, desc="drqn", unit="ep", disable=not progress)
    chunk = 0
    while done_eps < cfg.episodes:
        n = min(cfg.envs, cfg.episodes - done_eps)
        world = BatchGridWorld(sample_episodes(grid, n, seed * 100_003 + chunk), seed + chunk, off_map="stay")
        chunk += 1
        state = None
        hist = [{"v": [], "f": [], "a": [], "r": []} for _ in range(n)]
        for _ in range(cfg.train_max_steps):
            if world.done.all():
                break
            views, maps = world.observe()
            found = found_in_view(views, maps, world.agent)
            frames = torch.from_numpy(drqn_view(views, found, cfg.image))[:, None]
            with torch.no_grad():
                q, state = net(frames, state)
            eps = cfg.eps_start if steps < cfg.warmup_steps else max(
                cfg.eps_end, cfg.eps_start - (cfg.eps_start - cfg.eps_end) * (steps - cfg.warmup_steps) / cfg.eps_anneal_steps)
            greedy = q[:, 0].argmax(dim=1).numpy()
            explore = rng.random(n) < eps
            a = np.where(explore, rng.integers(0, grid.n_actions, n), greedy)
            active = ~world.done
            r = world.step(a)
            for i in np.flatnonzero(active):
                h = hist[i]
                h["v"].append(views[i])
                h["f"].append(found[i])
                h["a"].append(a[i])
                h["r"].append(r[i])
            steps += int(active.sum())
            if steps >= cfg.warmup_steps and replay.episodes:
                v, f, aa, rr, dd, mm = replay.sample(cfg.batch_seqs, cfg.seq_len)
                b, l1 = v.shape[:2]
                fr = torch.from_numpy(drqn_view(v.reshape(b * l1, 3, 3, 3), f.reshape(b * l1, 3, 3), cfg.image))
                fr = fr.reshape(b, l1, *fr.shape[1:])
                q_all, _ = net(fr)
                with torch.no_grad():
                    q_tgt, _ = target(fr)
                    y = td_targets(q_all[:, 1:].detach(), q_tgt[:, 1:], torch.from_numpy(rr), torch.from_numpy(dd), cfg.gamma)
                q_sa = q_all[:, :-1].gather(-1, torch.from_numpy(aa).long()[..., None]).squeeze(-1)
                mask = torch.from_numpy(mm)
                mask[:, : cfg.seq_len // 2] = 0.0  # first half: let the LSTM warm up, no loss
                loss = (torch.nn.functional.smooth_l1_loss(q_sa, y, reduction="none") * mask).sum() / mask.sum().clamp_min(1)
                opt.zero_grad()
                loss.backward()
                opt.step()
                losses.append(float(loss.detach()))
                updates += 1
                if updates % cfg.target_every == 0:
                    with torch.no_grad():
                        for pt, po in zip(target.parameters(), net.parameters(), strict=True):
                            pt.mul_(1 - cfg.tau).add_(po, alpha=cfg.tau)
        for i, h in enumerate(hist):
            replay.add(np.array(h["v"]), np.array(h["f"]), np.array(h["a"]), np.array(h["r"]))
            rewards_log.append(float(np.sum(h["r"])))
            del i
        done_eps += n
        bar.update(n)
    bar.close()
    curve = [float(np.mean(losses[i : i + 100])) for i in range(0, len(losses), 100)]
    return save_drqn(out / "drqn.pt", net, cfg, grid, seed, steps=steps, updates=updates, loss_curve=curve,
                     mean_reward_last_100=float(np.mean(rewards_log[-100:])))
