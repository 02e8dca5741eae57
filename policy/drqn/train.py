"""DRQN training by reward in the grid world, as the paper's off-the-shelf baseline (the
authors' setup, which follows Juliani's DRQN): double DQN; every 5 environment steps one
training step on 4 sequences of 8 steps from a replay of 1000 episodes, squared TD error with
the first half of each sequence masked (Lample & Chaplot), then a soft target update with
tau 0.001; epsilon 1 -> 0.1 over 10k steps after 10k random steps; reward +1 per new target and
nothing else; a wall bump leaves the agent in place. An episode cut at the step cap is not a
terminal state: its last transition has no successor frame and is left out of the loss.

Training snapshots its whole state (networks, optimiser, replay, random streams) every
`save_every` episodes, so `resume=True` continues an interrupted run to the same weights, or
extends a finished one to more episodes."""

from __future__ import annotations

import copy
import io
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from provenance import atomic_write_bytes, git_revision, stamp
from sim.gridworld import BatchGridWorld, GridConfig, sample_episodes

from ..nn.checkpoint import CheckpointError, read_torch_document
from .model import Drqn, drqn_view
from .plots import plot_drqn_training

FORMAT = "uavsearch-drqn/1"
STATE_FORMAT = "uavsearch-drqn-state/1"


@dataclass(frozen=True)
class DrqnConfig:
    image: int = 84
    episodes: int = 20_000
    envs: int = 16
    lr: float = 1e-4
    gamma: float = 0.99
    tau: float = 0.001
    #: environment steps (summed over the lock-stepped envs) between soft target updates
    target_every: int = 5
    #: environment steps between training steps
    update_every: int = 5
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
    #: episodes between resumable snapshots (0: none)
    save_every: int = 200

    def __post_init__(self) -> None:
        if self.image < 36:
            raise ValueError("image must be >= 36 px for the DRQN's convolutions")
        if self.episodes < 1 or self.envs < 1 or self.seq_len < 2 or self.batch_seqs < 1:
            raise ValueError("episodes, envs, batch_seqs >= 1 and seq_len >= 2")
        if self.update_every < 1 or self.target_every < 1 or self.save_every < 0:
            raise ValueError("update_every and target_every >= 1, save_every >= 0")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> DrqnConfig:
        known = set(cls.__dataclass_fields__)
        return cls(**{k: v for k, v in d.items() if k in known})


def found_in_view(views: np.ndarray, maps: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Which view cells hold a target the agent has already met (a target on a visited cell)."""
    n, _, h, w = maps.shape
    off = np.arange(-1, 2)
    ys = np.clip(pos[:, 1, None] + off, 0, h - 1)
    xs = np.clip(pos[:, 0, None] + off, 0, w - 1)
    visited = maps[np.arange(n)[:, None, None], 0, ys[:, :, None], xs[:, None, :]] > 0
    return views[:, 0].astype(bool) & visited


def _torch_bytes(doc: dict[str, Any]) -> bytes:
    buf = io.BytesIO()
    torch.save(doc, buf)
    return buf.getvalue()


def save_drqn(path: Path, net: Drqn, cfg: DrqnConfig, grid: GridConfig, seed: int, **extra: Any) -> Path:
    prov = stamp(None, seed)
    doc = {"format": FORMAT, "drqn_config": asdict(cfg), "grid_config": grid.to_dict(), "seed": seed,
           "git_revision": prov["git_revision"], "created_utc": prov["created_utc"],
           "state_dict": net.state_dict(), **extra}
    atomic_write_bytes(path, _torch_bytes(doc))
    return Path(path)


def load_drqn(path: str | Path) -> tuple[Drqn, dict]:
    doc = read_torch_document(path, FORMAT, ("drqn_config", "grid_config", "state_dict"))
    try:
        cfg = DrqnConfig.from_dict(doc["drqn_config"])
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"{path}: bad DRQN config ({e})") from e
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

    def add(self, views, found, actions, rewards, terminal: bool = True) -> None:
        """`terminal`: the episode ended by finding every target, not by the step cap."""
        if len(actions) == 0:
            return
        self.episodes.append((np.asarray(views), np.asarray(found), np.asarray(actions),
                              np.asarray(rewards, np.float32), bool(terminal)))
        if len(self.episodes) > self.capacity:
            self.episodes.pop(0)

    def sample(self, n: int, length: int):
        """(views (n, L+1, 3,3,3), found (n, L+1, 3,3), actions (n, L), rewards (n, L), done (n, L), valid (n, L))."""
        out_v, out_f, out_a, out_r, out_d, out_m = [], [], [], [], [], []
        for i in self.rng.integers(0, len(self.episodes), n):
            v, f, a, r, terminal = self.episodes[i]
            t = len(a)
            s = int(self.rng.integers(0, max(1, t - length + 1)))
            e = min(s + length, t)
            pad = length - (e - s)
            # the frame after the last action is not stored: a terminal step needs none (done),
            # a step cut by the cap does, so it is left out of the loss (valid 0)
            idx = np.minimum(np.r_[np.arange(s, e + 1), np.full(pad, e)], t - 1)
            out_v.append(v[idx])
            out_f.append(f[idx])
            out_a.append(np.r_[a[s:e], np.zeros(pad, a.dtype)])
            out_r.append(np.r_[r[s:e], np.zeros(pad, np.float32)])
            done = np.zeros(length, np.float32)
            valid = np.r_[np.ones(e - s), np.zeros(pad)].astype(np.float32)
            if e == t:
                if terminal:
                    done[e - s - 1] = 1.0
                else:
                    valid[e - s - 1] = 0.0
            out_d.append(done)
            out_m.append(valid)
        return tuple(map(np.stack, (out_v, out_f, out_a, out_r, out_d, out_m)))


def td_targets(q_next_online: torch.Tensor, q_next_target: torch.Tensor, rewards: torch.Tensor,
               done: torch.Tensor, gamma: float) -> torch.Tensor:
    """Double DQN: the online net picks the next action, the target net values it."""
    a_star = q_next_online.argmax(dim=-1, keepdim=True)
    return rewards + gamma * (1.0 - done) * q_next_target.gather(-1, a_star).squeeze(-1)


def epsilon(cfg: DrqnConfig, steps: int) -> float:
    if steps < cfg.warmup_steps:
        return cfg.eps_start
    frac = (steps - cfg.warmup_steps) / cfg.eps_anneal_steps
    return max(cfg.eps_end, cfg.eps_start - (cfg.eps_start - cfg.eps_end) * frac)


class DrqnLearner:
    """The networks, optimiser, replay and counters: everything a snapshot must hold."""

    def __init__(self, cfg: DrqnConfig, grid: GridConfig, seed: int) -> None:
        torch.manual_seed(seed)
        self.cfg, self.grid, self.seed = cfg, grid, seed
        self.rng = np.random.default_rng([seed, 0xD2])
        self.net = Drqn(grid.n_actions, cfg.image)
        self.target = copy.deepcopy(self.net)
        # fused: one kernel over all 3.9M parameters; the per-tensor loop was a third of a step
        self.opt = torch.optim.Adam(self.net.parameters(), lr=cfg.lr, fused=True)
        self.replay = EpisodeReplay(cfg.buffer_episodes, self.rng)
        self.steps = self.updates = self.done_eps = self.chunk = 0
        self.rewards: list[float] = []
        self.timeouts: list[bool] = []
        self.losses: list[float] = []

    # -- one training step -------------------------------------------------------------
    def frames(self, views: np.ndarray, found: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
        """The distinct images among these steps' views, and which one each step shows: a 3x3
        view takes few values, so this saves most of the convolution work."""
        lead = views.shape[:-3]
        codes = np.concatenate([views.reshape(-1, 27), found.reshape(-1, 9)], axis=1).astype(np.uint8)
        _, first, inverse = np.unique(codes, axis=0, return_index=True, return_inverse=True)
        fr = drqn_view(views.reshape(-1, 3, 3, 3)[first], found.reshape(-1, 3, 3)[first], self.cfg.image)
        return torch.from_numpy(fr), torch.from_numpy(inverse.reshape(lead))

    def learn(self) -> None:
        cfg = self.cfg
        v, f, aa, rr, dd, mm = self.replay.sample(cfg.batch_seqs, cfg.seq_len)
        fr, idx = self.frames(v, f)
        q_all, _ = self.net(fr, index=idx)
        with torch.no_grad():
            q_tgt, _ = self.target(fr, index=idx)
            y = td_targets(q_all[:, 1:].detach(), q_tgt[:, 1:], torch.from_numpy(rr), torch.from_numpy(dd), cfg.gamma)
        q_sa = q_all[:, :-1].gather(-1, torch.from_numpy(aa).long()[..., None]).squeeze(-1)
        mask = torch.from_numpy(mm)
        mask[:, : cfg.seq_len // 2] = 0.0  # first half: let the LSTM warm up, no loss
        loss = ((q_sa - y) ** 2 * mask).sum() / mask.sum().clamp_min(1)
        self.opt.zero_grad()
        loss.backward()
        self.opt.step()
        self.losses.append(float(loss.detach()))
        self.updates += 1

    @torch.no_grad()
    def soft_update(self) -> None:
        torch._foreach_lerp_(list(self.target.parameters()), list(self.net.parameters()), self.cfg.tau)

    # -- one lock-stepped batch of episodes ------------------------------------------------
    def play_chunk(self, n: int) -> None:
        cfg, grid = self.cfg, self.grid
        world = BatchGridWorld(sample_episodes(grid, n, self.seed * 100_003 + self.chunk), self.seed + self.chunk,
                               off_map="stay")
        self.chunk += 1
        state = None
        hist = [{"v": [], "f": [], "a": [], "r": []} for _ in range(n)]
        for _ in range(cfg.train_max_steps):
            if world.done.all():
                break
            views, maps = world.observe()
            found = found_in_view(views, maps, world.agent)
            with torch.no_grad():
                fr, idx = self.frames(views, found)
                q, state = self.net(fr, state, index=idx[:, None])
            greedy = q[:, 0].argmax(dim=1).numpy()
            explore = self.rng.random(n) < epsilon(cfg, self.steps)
            a = np.where(explore, self.rng.integers(0, grid.n_actions, n), greedy)
            active = ~world.done
            r = world.step(a)
            for i in np.flatnonzero(active):
                h = hist[i]
                h["v"].append(views[i])
                h["f"].append(found[i])
                h["a"].append(a[i])
                h["r"].append(r[i])
            before = self.steps
            self.steps += int(active.sum())
            if self.steps >= cfg.warmup_steps and self.replay.episodes:
                for _ in range(before // cfg.update_every, self.steps // cfg.update_every):
                    self.learn()
            for _ in range(before // cfg.target_every, self.steps // cfg.target_every):
                if self.updates:
                    self.soft_update()
        for i, h in enumerate(hist):
            self.replay.add(np.array(h["v"]), np.array(h["f"]), np.array(h["a"]), np.array(h["r"]),
                            terminal=bool(world.done[i]))
            self.rewards.append(float(np.sum(h["r"])))
            self.timeouts.append(not bool(world.done[i]))
        self.done_eps += n

    # -- snapshots -----------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {"format": STATE_FORMAT, "drqn_config": asdict(self.cfg), "grid_config": self.grid.to_dict(),
                "seed": self.seed, "net": self.net.state_dict(), "target": self.target.state_dict(),
                "opt": self.opt.state_dict(), "replay": self.replay.episodes, "rng": self.rng.bit_generator.state,
                "torch_rng": torch.get_rng_state(), "counters": [self.steps, self.updates, self.done_eps, self.chunk],
                "rewards": self.rewards, "timeouts": self.timeouts, "losses": self.losses}

    def restore(self, path: Path) -> None:
        doc = read_torch_document(path, STATE_FORMAT, ("net", "target", "opt", "replay", "rng", "counters"))
        theirs = replace(DrqnConfig.from_dict(doc["drqn_config"]), episodes=self.cfg.episodes)
        if theirs != self.cfg or doc["grid_config"] != self.grid.to_dict() or doc["seed"] != self.seed:
            raise CheckpointError(f"{path}: snapshot of another run (config, grid or seed differ); "
                                  "only --episodes may change on resume")
        self.net.load_state_dict(doc["net"])
        self.target.load_state_dict(doc["target"])
        self.opt.load_state_dict(doc["opt"])
        self.replay.episodes = list(doc["replay"])
        self.rng.bit_generator.state = doc["rng"]
        torch.set_rng_state(doc["torch_rng"])
        self.steps, self.updates, self.done_eps, self.chunk = doc["counters"]
        self.rewards, self.timeouts, self.losses = list(doc["rewards"]), list(doc["timeouts"]), list(doc["losses"])


def train_drqn(cfg: DrqnConfig, grid: GridConfig, out: str | Path, seed: int = 0, progress: bool = True,
               resume: bool = False) -> Path:
    """Train, writing OUT/drqn.pt (the policy), OUT/drqn_state.pt (the resumable snapshot) and
    OUT/drqn_training.png (reward, timeouts and loss)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    git_revision()  # the code that trains is the code at the start: pin the cached revision now
    snap = out / "drqn_state.pt"
    learner = DrqnLearner(cfg, grid, seed)
    if resume and snap.exists():
        learner.restore(snap)
    bar = tqdm(total=cfg.episodes, initial=min(learner.done_eps, cfg.episodes), desc="drqn", unit="ep",
               disable=not progress)
    last_save = learner.done_eps
    while learner.done_eps < cfg.episodes:
        n = min(cfg.envs, cfg.episodes - learner.done_eps)
        learner.play_chunk(n)
        bar.update(n)
        bar.set_postfix(eps=f"{epsilon(cfg, learner.steps):.2f}", reward=f"{np.mean(learner.rewards[-100:]):.2f}")
        if cfg.save_every and learner.done_eps - last_save >= cfg.save_every:
            atomic_write_bytes(snap, _torch_bytes(learner.state()))
            last_save = learner.done_eps
    bar.close()
    if cfg.save_every:
        atomic_write_bytes(snap, _torch_bytes(learner.state()))
    losses = learner.losses
    plot_drqn_training(learner.rewards, learner.timeouts, losses, grid.n_targets, out / "drqn_training.png")
    curve = [float(np.mean(losses[i : i + 100])) for i in range(0, len(losses), 100)]
    return save_drqn(out / "drqn.pt", learner.net, cfg, grid, seed, steps=learner.steps, updates=learner.updates,
                     loss_curve=curve, mean_reward_last_100=float(np.mean(learner.rewards[-100:])),
                     timeout_pct_last_100=100.0 * float(np.mean(learner.timeouts[-100:])))
