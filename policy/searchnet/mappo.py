"""MAPPO-style fine-tuning of the team searchnet (issue 29): decentralised actors, one
centralised critic (Yu et al., 2022, "The surprising effectiveness of PPO in cooperative
multi-agent games"), after DAgger.

- The actor is the team network itself, shared by the agents (parameter sharing), on each
  agent's decentralised input (policy.searchnet.team.team_planes).
- The critic sees the joint state: the same egocentric planes (shared belief, every agent's
  cell) plus the truth (the unfound targets' cells, policy.searchnet.ppo.truth_plane's
  privilege), so it knows where all agents are and what is left; it is thrown away after
  training and costs nothing in flight. It gives each agent a value of the team's return.
- Reward: the team's, +target_reward per target any agent recovers, -step_cost per joint step;
  each agent's advantage is GAE of that reward on its own value estimate.
- Execution as in flight: each agent samples its move, the joint move goes through the
  fixed-priority separation. Where separation replaced an agent's sample (a teammate held the
  cell) the step is left out of the actor's loss (its probability under the actor is not the
  sample's); the critic still learns from it.
- The critic starts from the actor's weights (the truth plane's first-layer weights zero) and
  is trained alone for `critic_warmup` updates before the actor moves, so the first advantages
  are not a random critic's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, replace

import numpy as np
import torch
import torch.nn.functional as F

from sim.gridworld import GridConfig, sample_episodes
from sim.gridworld.team import TeamGridWorld, team_starts

from ..belief.shared import SharedBelief
from ..team.base import separate, team_observe
from .encode import egocentric
from .model import SearchNet
from .team import padded_valid, team_planes


@dataclass(frozen=True)
class MappoConfig:
    updates: int = 6
    #: episodes per setting and update, stepped together in one team world
    episodes: int = 48
    critic_warmup: int = 2
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.1
    epochs: int = 2
    minibatch: int = 512
    lr: float = 3e-5
    critic_lr: float = 1e-3
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5
    target_reward: float = 1.0
    step_cost: float = 0.1
    #: rollouts' step cap: max_steps_factor * h * w / N joint steps
    max_steps_factor: float = 1.5
    #: training episodes from seeds >= this, far from every test and validation seed
    seed_base: int = 2_500_000

    def __post_init__(self) -> None:
        if self.updates < 1 or self.episodes < 1 or self.epochs < 1 or self.minibatch < 1 or self.critic_warmup < 0:
            raise ValueError(f"MappoConfig needs positive counts (got {self})")
        if not (0 < self.gamma <= 1 and 0 <= self.gae_lambda <= 1 and 0 < self.clip < 1):
            raise ValueError(f"MappoConfig: gamma in (0, 1], gae_lambda in [0, 1], clip in (0, 1) (got {self})")

    def to_dict(self) -> dict:
        return asdict(self)


def make_critic(actor: SearchNet) -> SearchNet:
    """The centralised critic: the actor's network with the truth plane added (zero weights)."""
    cfg = actor.cfg
    critic = SearchNet(replace(cfg, privileged_channels=1))
    sd = {k: v.clone() for k, v in actor.state_dict().items()}
    w = sd["conv1.weight"]
    at = cfg.field_planes  # the truth comes after every actor plane, before the crop's own
    sd["conv1.weight"] = torch.cat([w[:, :at], torch.zeros_like(w[:, :1]), w[:, at:]], dim=1)
    critic.load_state_dict(sd)
    return critic


def _truth(world: TeamGridWorld, k: int) -> np.ndarray:
    """(n * N, 1, h, w) the unfound targets' cells, repeated for each agent's row."""
    cfg, n = world.cfg, world.n
    tg = world.targets()
    occ = np.zeros((n, cfg.height, cfg.width), np.float32)
    rows = np.broadcast_to(np.arange(n)[:, None], world.found.shape)
    keep = ~world.found
    occ[rows[keep], tg[..., 1][keep], tg[..., 0][keep]] = 1.0
    return np.repeat(occ[:, None], k, axis=0)


def team_rollout(actor: SearchNet, critic: SearchNet, grid: GridConfig, k: int, mc: MappoConfig, seed: int,
                 gen: torch.Generator) -> dict[str, torch.Tensor]:
    """One batch of whole team episodes with sampling actors; flat per-agent steps with
    advantages and returns (active episodes only), and per-episode makespans."""
    n = mc.episodes
    ep = sample_episodes(grid, n, seed)
    world = TeamGridWorld(ep, team_starts(ep, k), seed)
    shared = SharedBelief(grid, n, k)
    rows = np.repeat(np.arange(n)[:, None], k, axis=1)
    limit = min(max(int(mc.max_steps_factor * grid.width * grid.height / k), 1), grid.t_e + 1)
    steps: list[dict[str, torch.Tensor]] = []
    for _ in range(limit):
        if world.done.all():
            break
        obs = team_observe(world)
        shared.update(obs.views, obs.positions, obs.t, obs.active)
        planes = torch.from_numpy(team_planes(shared.belief.planes(), rows, obs.positions, actor.cfg.team_planes))
        pos_np = np.asarray(obs.positions, np.int64)
        pos = torch.from_numpy(pos_np.reshape(n * k, 2))
        valid = np.asarray(obs.valid)
        mask = torch.from_numpy(padded_valid(valid.reshape(n * k, -1), actor.cfg.n_actions))
        truth = torch.from_numpy(_truth(world, k))
        with torch.no_grad():
            logits = actor(egocentric(planes, pos), mask)
            a = torch.multinomial(F.softmax(logits, dim=1), 1, generator=gen).squeeze(1)
            logp = F.log_softmax(logits, dim=1).gather(1, a[:, None]).squeeze(1)
            v = critic.value(egocentric(torch.cat([planes, truth], dim=1), pos))
        a_n = valid.shape[-1]
        prefs = np.where(np.arange(a_n) == np.minimum(a.numpy(), a_n - 1).reshape(n, k, 1), 1.0, 0.0)
        joint = separate(pos_np, prefs, valid)
        kept = torch.from_numpy(joint.reshape(n * k) == a.numpy())
        active = torch.from_numpy(np.repeat(obs.active, k))
        newly = world.step(joint)
        r = torch.from_numpy(np.repeat(mc.target_reward * newly - mc.step_cost, k).astype(np.float32)) * active
        steps.append({"planes": planes, "truth": truth, "pos": pos, "mask": mask, "a": a, "logp": logp, "v": v,
                      "r": r, "active": active, "kept": kept & active,
                      "done": torch.from_numpy(np.repeat(world.done.copy(), k))})
    T, m = len(steps), n * k
    adv = torch.zeros(T, m)
    last = torch.zeros(m)
    for t in reversed(range(T)):
        s = steps[t]
        nxt_v = steps[t + 1]["v"] if t + 1 < T else torch.zeros(m)
        nonterm = (~s["done"]).float()
        delta = s["r"] + mc.gamma * nxt_v * nonterm - s["v"]
        last = delta + mc.gamma * mc.gae_lambda * nonterm * last
        adv[t] = last * s["active"]
    keep = torch.stack([s["active"] for s in steps])
    flat = {key: torch.stack([s[key] for s in steps])[keep]
            for key in ("planes", "truth", "pos", "mask", "a", "logp", "v", "kept")}
    flat["adv"] = adv[keep]
    flat["ret"] = flat["adv"] + flat["v"]
    flat["moves"] = torch.from_numpy(world.t.copy())
    flat["success"] = torch.from_numpy(world.success.copy())
    return flat


def mappo_update(actor: SearchNet, critic: SearchNet, opt_a: torch.optim.Optimizer, opt_c: torch.optim.Optimizer,
                 batch: dict[str, torch.Tensor], mc: MappoConfig, gen: torch.Generator,
                 train_actor: bool) -> dict[str, float]:
    n = len(batch["a"])
    actor.train()
    critic.train()
    stats = {"pg_loss": 0.0, "v_loss": 0.0, "entropy": 0.0, "clipfrac": 0.0}
    count = 0
    for _ in range(mc.epochs):
        order = torch.randperm(n, generator=gen)
        for s in range(0, n, mc.minibatch):
            b = order[s: s + mc.minibatch]
            v = critic.value(egocentric(torch.cat([batch["planes"][b], batch["truth"][b]], dim=1), batch["pos"][b]))
            v_loss = F.mse_loss(v, batch["ret"][b])
            loss = mc.vf_coef * v_loss
            if train_actor:
                kb = b[batch["kept"][b]]
                logits = actor(egocentric(batch["planes"][kb], batch["pos"][kb]), batch["mask"][kb])
                logp_all = F.log_softmax(logits, dim=1)
                logp = logp_all.gather(1, batch["a"][kb][:, None]).squeeze(1)
                ratio = (logp - batch["logp"][kb]).exp()
                adv = batch["adv"][kb]
                adv = (adv - adv.mean()) / (adv.std() + 1e-8) if len(kb) > 1 else adv
                pg = torch.max(-adv * ratio, -adv * ratio.clamp(1 - mc.clip, 1 + mc.clip)).mean()
                p = logp_all.exp()
                ent = -(p * logp_all.clamp(min=-30)).sum(1).mean()
                loss = loss + pg - mc.ent_coef * ent
                stats["pg_loss"] += float(pg.detach())
                stats["entropy"] += float(ent.detach())
                stats["clipfrac"] += float(((ratio.detach() - 1).abs() > mc.clip).float().mean())
            opt_a.zero_grad(set_to_none=True)
            opt_c.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(actor.parameters(), mc.max_grad_norm)
            torch.nn.utils.clip_grad_norm_(critic.parameters(), mc.max_grad_norm)
            if train_actor:
                opt_a.step()
            opt_c.step()
            stats["v_loss"] += float(v_loss.detach())
            count += 1
    actor.eval()
    critic.eval()
    return {key: v / max(count, 1) for key, v in stats.items()}


def run_mappo(actor: SearchNet, settings: list[tuple[GridConfig, int]], mc: MappoConfig,
              on_update: Callable[[int, dict, SearchNet], None] | None = None) -> list[dict]:
    """Updates 0 .. mc.updates - 1 over the (grid, N) settings (one batch each per update);
    update u's episodes come from seed seed_base + 100 u + setting. on_update(u, stats, actor)
    after each update where the actor moved (the trainer validates there)."""
    critic = make_critic(actor)
    opt_a = torch.optim.Adam(actor.parameters(), lr=mc.lr)
    opt_c = torch.optim.Adam(critic.parameters(), lr=mc.critic_lr)
    history = []
    for u in range(mc.critic_warmup + mc.updates):
        train_actor = u >= mc.critic_warmup
        stats: dict = {"update": u - mc.critic_warmup, "critic_only": not train_actor}
        for s, (grid, k) in enumerate(settings):
            gen = torch.Generator().manual_seed(mc.seed_base + 100 * u + s)
            batch = team_rollout(actor, critic, grid, k, mc, mc.seed_base + 100 * u + s, gen)
            st = mappo_update(actor, critic, opt_a, opt_c, batch, mc, gen, train_actor)
            tag = f"{grid.width}x{grid.height}x{k}"
            stats |= {f"{tag}_makespan": float(batch["moves"].float().mean()),
                      f"{tag}_success": float(batch["success"].float().mean()),
                      f"{tag}_kept": float(batch["kept"].float().mean()), **{f"{tag}_{key}": v for key, v in st.items()}}
        history.append(stats)
        if train_actor and on_update is not None:
            on_update(u - mc.critic_warmup, stats, actor)
    return history
